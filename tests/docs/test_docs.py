# The docs still describe the program and the module: every `uplvsm ...` command a page quotes (in code) parses, i.e.
# its subcommand exists and `uplvsm <subcommand> --help` lists each flag quoted with it; every `uplvsm.x.y` Python
# name a page quotes exists; the Python and C++ snippets are exactly the example files the tests run; the README's
# quick start runs as written; every config key is documented once in docs/config.md; every test the parity ledger
# (docs/parity.md) names exists.
import functools
import json
import os
import pathlib
import re
import shlex
import subprocess

import pytest

REPO = pathlib.Path(os.environ.get("UPLVSM_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
CLI = os.environ.get("UPLVSM_CLI", str(REPO / "build" / "uplvsm"))
# The user pages and the lab notebook (docs/research/): its commands are records of what ran, and still run.
PAGES = [REPO / "README.md"] + sorted((REPO / "docs").rglob("*.md"))
EXAMPLE = REPO / "examples" / "render_two_photos"


def code_of(page):
    """The page's code: fenced blocks (continuation lines joined) and inline code spans, one string each."""
    text = page.read_text()
    blocks = re.findall(r"^```[^\n]*\n(.*?)^```", text, flags=re.S | re.M)
    prose = re.sub(r"^```[^\n]*\n.*?^```", "", text, flags=re.S | re.M)
    spans = re.findall(r"`([^`\n]+)`", prose.replace("`\n", "` ").replace("\n", " "))
    lines = [line for block in blocks for line in block.replace("\\\n", " ").splitlines()]
    return lines + spans


@functools.lru_cache(maxsize=None)
def help_text(path):
    run = subprocess.run([CLI, *path, "--help"], capture_output=True, text=True, env=dict(os.environ, UPLVSM_NO_REEXEC="1"))
    assert run.returncode == 0, f"`uplvsm {' '.join(path)} --help` failed: {run.stderr}"
    return run.stdout


def subcommands(path):
    text = help_text(path)
    section = text.split("Subcommands:" if "Subcommands:" in text else "SUBCOMMANDS:")[-1] if re.search(
        r"Subcommands:|SUBCOMMANDS:", text) else ""
    return set(re.findall(r"^\s{2}([a-z][a-z0-9-]*)\s", section, flags=re.M))


def quoted_commands():
    """(page, command path, flags) of every `uplvsm ...` invocation in the pages' code."""
    out = []
    for page in PAGES:
        for code in code_of(page):
            for m in re.finditer(r"(?:^|(?<=[\s`(]))(?:[\w.$(){}/-]*/)?uplvsm((?:[ \t]+[^\s|;&`#]+)*)", code):
                words = m.group(1).split()
                path = []
                while words and words[0] in subcommands(tuple(path)):
                    path.append(words.pop(0))
                flags = [re.match(r"--[a-z0-9-]+", w).group(0) for w in words if re.match(r"--[a-z0-9-]+", w)]
                out.append((page.name, tuple(path), flags))
    return out


def test_every_quoted_command_and_flag_parses():
    commands = quoted_commands()
    assert len({c[1] for c in commands}) >= 10, "the docs quote fewer subcommands than expected: parsing broke?"
    problems = []
    for page, path, flags in commands:
        listed = set(re.findall(r"--[a-z0-9-]+", help_text(path)))
        problems += [f"{page}: `uplvsm {' '.join(path)}` has no {flag}" for flag in flags if flag not in listed]
    assert not problems, "\n".join(sorted(set(problems)))


def test_every_quoted_python_name_exists():
    uplvsm = pytest.importorskip("uplvsm")
    missing = []
    for page in PAGES:
        for code in code_of(page):
            for name in re.findall(r"(?<![\w/])uplvsm((?:\.[A-Za-z_]\w*)+)", code):
                if re.fullmatch(r"\.(h|cpp|py|json|md|so)", name):  # a file name, not a Python name
                    continue
                obj = uplvsm
                for part in name.strip(".").split("."):
                    if not hasattr(obj, part):
                        missing.append(f"{page.name}: uplvsm{name}")
                        break
                    obj = getattr(obj, part)
    assert not missing, "\n".join(sorted(set(missing)))


def test_quoted_snippets_are_the_tested_examples():
    """The README's Python example and docs/cpp.md's CMake project and C++ program are the files tests/install runs."""
    for page, names in [("README.md", ["render_two_photos.py"]), ("docs/python.md", ["render_two_photos.py"]),
                        ("docs/cpp.md", ["CMakeLists.txt", "render_two_photos.cpp"])]:
        text = (REPO / page).read_text()
        for name in names:
            assert (EXAMPLE / name).read_text() in text, f"{page} does not quote examples/render_two_photos/{name} exactly"


def test_make_demo_report_models_are_key_value_lists():
    """`make demo`'s report specs (`--model "key=value,key=value"`) split at every comma: one inside a caption stops
    the main job at its last step."""
    specs = re.findall(r'--model "([^"]*)"', (REPO / "Makefile").read_text())
    assert len(specs) >= 4, "the Makefile's report specs were not found: parsing broke?"
    bad = [part for spec in specs for part in spec.split(",") if not re.match(r"[a-z_]+=", part)]
    assert not bad, "Makefile: report --model parts that are not key=value (a comma in a caption?): " + "; ".join(bad)


FIXTURES = pathlib.Path(os.environ.get("UPLVSM_FIXTURES", REPO.parent / "shared" / "fixtures"))


def fixtures_or_skip():
    """The reference fixture pack (outside the repository): skip without it, fail under CI (as the other tests)."""
    if FIXTURES.is_dir():
        return FIXTURES
    message = (f"reference fixture pack not found: {FIXTURES} (what it holds and how it is made: docs/development.md, "
               '"The reference fixture pack")')
    if os.environ.get("CI") in ("true", "1") or os.environ.get("UPLVSM_REQUIRE_FIXTURES") == "1":
        pytest.fail(message)
    pytest.skip(message)


def readme_section(title):
    text = (REPO / "README.md").read_text()
    match = re.search(rf"^## {re.escape(title)}[^\n]*\n(.*?)(?=^## |\Z)", text, flags=re.S | re.M)
    assert match, f"README.md has no section '## {title}'"
    return match.group(1)


def test_readme_quick_start_renders_two_photos(tmp_path):
    """The README's quick start, as a user types it, with the fixture pack's small authors'-format checkpoint (random
    weights, the official `checkpoint.pt` layout) for `uplvsm_x224.pt` and two fixture frames for the photos: it runs
    and writes every file the README says it writes."""
    fixtures = fixtures_or_skip()
    section = readme_section("Quick start")
    commands = [line for block in re.findall(r"^```sh\n(.*?)^```", section, flags=re.S | re.M)
                for line in block.replace("\\\n", " ").splitlines() if re.search(r"uplvsm render\b", line)]
    assert len(commands) == 1, f"the quick start should show one `uplvsm render` command, found {commands}"
    words = shlex.split(commands[0], comments=True)
    assert re.fullmatch(r"(.*/)?uplvsm", words[0]) and words[1] == "render", commands[0]
    for flag in ["--checkpoint", "--images", "--out"]:
        assert flag in words, f"the quick start's command has no {flag}: {commands[0]}"

    # Two photos: frames 1 and 13 of a RealEstate10K-like fixture scene, as PNG files (as tests/install does).
    env = dict(os.environ, UPLVSM_NO_REEXEC="1")
    convert = subprocess.run([CLI, "dataset", "convert", "--from", "chunks", "--input",
                              str(fixtures / "re10k_chunks" / "root" / "test"), "--output", str(tmp_path / "lvsm")],
                             capture_output=True, text=True, env=env)
    assert convert.returncode == 0, convert.stdout + convert.stderr
    scene = tmp_path / "lvsm" / "images" / "20e408dd375292a1"
    photos = [str(scene / "00001.png"), str(scene / "00013.png")]

    argv = [CLI, "render"]
    i, out = 2, None
    while i < len(words):
        if words[i] == "--checkpoint":
            argv += ["--checkpoint", str(fixtures / "official_uplvsm" / "checkpoint.pt")]
            i += 2
        elif words[i] == "--images":
            argv += ["--images", *photos]
            i += 3
        else:
            if words[i - 1] == "--out":
                out = tmp_path / words[i]
            argv.append(words[i])
            i += 1
    run = subprocess.run(argv, capture_output=True, text=True, env=env, cwd=tmp_path)
    assert run.returncode == 0, f"{' '.join(argv)}\n{run.stdout}{run.stderr}"

    # "You get `out/mine/video.mp4` (and `video.gif`, ...)": every file the paragraph after the command names.
    after = section.split(commands[0], 1)[1].split("```", 1)[1].lstrip().split("\n\n", 1)[0]
    promised = re.findall(r"`([\w./-]+\.(?:mp4|gif|png|json))`", after)
    assert any(p.endswith(".mp4") for p in promised), f"the quick start names no output video: {after}"
    mp4 = subprocess.run([CLI, "info"], capture_output=True, text=True, env=env).stdout
    for name in promised:
        path = tmp_path / name if "/" in name else out / name
        if name.endswith(".mp4") and re.search(r"MP4 output\s+off", mp4):
            continue  # built without FFmpeg: render writes the GIF and the PNG frames only
        assert path.is_file() and path.stat().st_size > 0, f"the quick start promises {name}, not written"
        if name.endswith(".mp4"):
            assert path.read_bytes()[4:8] == b"ftyp", f"{path} is not an MP4"
    listing = json.loads((out / "videos.json").read_text())
    frames, size = re.search(r"(\d+) frames", after), re.search(r"(\d+)x(\d+)", after)
    if frames:
        assert listing[0]["frames"] == int(frames.group(1)), "the quick start's frame count is not what render wrote"
    if size:
        assert [listing[0]["width"], listing[0]["height"]] == [int(size.group(1)), int(size.group(2))], (
            "the quick start's image size is not what render wrote")


def config_keys_in_code():
    """Every config key the reader accepts: the `f("key", ...)` lines of each `<section>_fields` list in
    src/uplvsm/core/config.cpp (the one list both reading and writing use), plus the top-level `name`."""
    source = (REPO / "src" / "uplvsm" / "core" / "config.cpp").read_text()
    sections = {"transformer": "model.transformer", "dinov2": "model.dinov2", "model": "model",
                "training": "training", "dataset": "dataset", "eval": "eval"}
    keys = {"name"} if re.search(r'r\.get\("name"', source) else set()
    for name, body in re.findall(r"void (\w+)_fields\(C& c, F&& f\) \{\n(.*?)^\}", source, flags=re.S | re.M):
        assert name in sections, f"config.cpp has a field list docs/config.md does not know: {name}_fields"
        keys |= {f"{sections[name]}.{key}" for key in re.findall(r'f\("(\w+)"', body)}
    assert len(keys) > 50, "config.cpp's field lists were not found: parsing broke?"
    return keys


def resolved_config(path):
    """A config file's JSON with its "extends" chain resolved as load_config does (sections merged key by key)."""
    config = json.loads(path.read_text())
    base = config.pop("extends", None)
    if base is None:
        return config
    merged = resolved_config(path.parent / base)

    def merge(into, over):
        for key, value in over.items():
            if isinstance(value, dict) and isinstance(into.get(key), dict):
                merge(into[key], value)
            else:
                into[key] = value
    merge(merged, config)
    return merged


def config_keys_documented():
    """(section.key, ...) of every row of docs/config.md's key tables: the section from the heading (`## `model``),
    the keys from the row's first cell (`a`, `b` documents both)."""
    documented, section = [], None
    for line in (REPO / "docs" / "config.md").read_text().splitlines():
        heading = re.match(r"#{2,3} `([\w.]+)`", line)
        if heading:
            section = heading.group(1)
        elif line.startswith("#"):
            section = None
        elif section and line.startswith("| `"):
            cell = line.split("|")[1]
            documented += [key if section == "name" else f"{section}.{key}" for key in re.findall(r"`(\w+)`", cell)]
    return documented


def test_training_commands_say_what_the_perceptual_loss_needs():
    """A quoted `uplvsm train` or `uplvsm study` with a config whose perceptual weight is above 0 gives --vgg19 or
    the explicit opt-out: without either it refuses to start, so the page's command would not run as written."""
    problems, checked = [], 0
    for page in PAGES:
        for code in code_of(page):
            for m in re.finditer(r"uplvsm (?:train|study [a-z-]+)((?:[ \t]+[^\s|;&`#]+)*)", code):
                words = m.group(1).split()
                configs = [w for w in words if w.startswith("configs/") and w.endswith(".json")]
                weighted = [c for c in configs if (REPO / c).exists()  # the notebook also quotes retired configs
                            and resolved_config(REPO / c).get("training", {}).get("perceptual_loss_weight", 0) > 0]
                if not weighted or "--help" in words:
                    continue
                checked += 1
                if "--vgg19" not in words and "training.perceptual_loss_weight=0" not in words:
                    problems.append(f"{page.name}: `{m.group(0)}` ({', '.join(weighted)}) gives no --vgg19")
    assert checked >= 3, "no full-size training command found: parsing broke?"
    assert not problems, "\n".join(problems)


def test_every_config_key_is_documented_once():
    code, documented = config_keys_in_code(), config_keys_documented()
    twice = sorted({key for key in documented if documented.count(key) > 1})
    assert not twice, "docs/config.md documents these keys more than once: " + ", ".join(twice)
    missing, stale = sorted(code - set(documented)), sorted(set(documented) - code)
    assert not missing, "config keys docs/config.md does not document: " + ", ".join(missing)
    assert not stale, "docs/config.md documents keys the config does not have: " + ", ".join(stale)


def anchors_of(page):
    """GitHub's heading anchors of a page: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"^```.*?^```", "", page.read_text(), flags=re.S | re.M)
    return {re.sub(r"[^\w\- ]", "", h.strip().lower()).replace(" ", "-") for h in re.findall(r"^#+ (.*)$", text, re.M)}


def test_relative_links_resolve():
    """Every relative link of README.md, docs/ and docs/research/ names a file that exists, and a `#anchor` a heading
    of that page."""
    pages = [REPO / "README.md"] + sorted((REPO / "docs").rglob("*.md"))
    broken = []
    for page in pages:
        text = re.sub(r"^```.*?^```", "", page.read_text(), flags=re.S | re.M)
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+:", target):
                continue  # https:, mailto:
            path, _, anchor = target.partition("#")
            file = (page.parent / path).resolve() if path else page
            if not file.exists():
                broken.append(f"{page.relative_to(REPO)}: {target} (no such file)")
            elif anchor and file.suffix == ".md" and anchor not in anchors_of(file):
                broken.append(f"{page.relative_to(REPO)}: {target} (no such heading)")
    assert not broken, "\n".join(broken)


def parity_rows():
    """(table heading, row cells) of every row of docs/parity.md's tables, header and rule lines left out."""
    rows, heading, header = [], None, None
    for line in (REPO / "docs" / "parity.md").read_text().splitlines():
        if line.startswith("#"):
            heading, header = line.lstrip("# "), None
        elif line.startswith("|"):
            cells = [c.strip() for c in re.split(r"(?<!\\)\|", line.strip())[1:-1]]
            if header is None:
                header = cells
            elif not all(re.fullmatch(r":?-+:?", c) for c in cells):
                assert len(cells) == len(header), f"docs/parity.md, {heading}: a row of {len(cells)} cells: {line[:80]}"
                rows.append((heading, dict(zip(header, cells))))
        else:
            header = None
    return rows


def test_parity_ledger_names_existing_tests():
    """docs/parity.md compares us with the official code at a pinned commit, row by row, each row naming the tests
    that guard it: every `Suite.Name` is a TEST, TEST_F or TEST_P of tests/, every `tests/python/file.py::test_name` a
    function of that file, and a row no test guards says `none` and is listed under "Rows without a test"."""
    page = (REPO / "docs" / "parity.md").read_text()
    intro = page.split("\n## ", 1)[0]
    assert "`d490397`" in intro, "docs/parity.md does not name the pinned official commit `d490397` before its tables"
    rows = parity_rows()
    assert len(rows) > 80 and all("test" in cells for _, cells in rows), "docs/parity.md's tables: parsing broke?"
    gtests = set()
    for source in (REPO / "tests").rglob("*.cpp"):
        gtests |= {f"{suite}.{name}" for suite, name in
                   re.findall(r"\bTEST(?:_F|_P)?\(\s*(\w+)\s*,\s*(\w+)\s*\)", source.read_text(errors="replace"))}
    problems, unguarded = [], 0
    for heading, cells in rows:
        cell, what = cells["test"], f"{heading}: {cells[next(iter(cells))][:60]}"
        if cell == "none":
            unguarded += 1
            continue
        names = re.findall(r"`([^`]+)`", cell)
        rest = re.sub(r"`[^`]+`", "", cell).replace(",", "").strip()
        if not names or rest:
            problems.append(f"{what}: test cell is not a list of `names` or `none`: {cell}")
        for name in names:
            python = re.fullmatch(r"(tests/[\w/]+\.py)::(test_\w+)", name)
            if python:
                file = REPO / python.group(1)
                if not (file.is_file() and re.search(rf"^\s*def {python.group(2)}\(", file.read_text(), re.M)):
                    problems.append(f"{what}: no `def {python.group(2)}` in {python.group(1)}")
            elif not re.fullmatch(r"\w+\.\w+", name):
                problems.append(f"{what}: `{name}` is neither Suite.Name nor tests/python/file.py::test_name")
            elif name not in gtests:
                problems.append(f"{what}: no TEST, TEST_F or TEST_P {name} in tests/")
    assert not problems, "docs/parity.md:\n" + "\n".join(problems)
    listed = re.search(r"^## Rows without a test\n(.*?)(?=^## |\Z)", page, re.S | re.M)
    assert listed, "docs/parity.md has no section '## Rows without a test'"
    bullets = len(re.findall(r"^- ", listed.group(1), re.M))
    assert bullets == unguarded, (f"docs/parity.md: {unguarded} rows say `none` but 'Rows without a test' lists "
                                  f"{bullets}")
