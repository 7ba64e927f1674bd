# The docs still describe the program and the module: every `uplvsm ...` command a page quotes (in code) parses, i.e.
# its subcommand exists and `uplvsm <subcommand> --help` lists each flag quoted with it; every `uplvsm.x.y` Python
# name a page quotes exists; the README's Python and C++ snippets are exactly the example files the tests run.
import functools
import os
import pathlib
import re
import subprocess

import pytest

REPO = pathlib.Path(os.environ.get("UPLVSM_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
CLI = os.environ.get("UPLVSM_CLI", str(REPO / "build" / "uplvsm"))
PAGES = [REPO / "README.md"] + sorted((REPO / "docs").glob("*.md"))
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


def test_readme_snippets_are_the_tested_examples():
    readme = (REPO / "README.md").read_text()
    for name in ["render_two_photos.py", "CMakeLists.txt", "render_two_photos.cpp"]:
        assert (EXAMPLE / name).read_text() in readme, f"README.md does not quote examples/render_two_photos/{name} exactly"


def test_make_demo_report_models_are_key_value_lists():
    """`make demo`'s report specs (`--model "key=value,key=value"`) split at every comma: one inside a caption stops
    the main job at its last step."""
    specs = re.findall(r'--model "([^"]*)"', (REPO / "Makefile").read_text())
    assert len(specs) >= 4, "the Makefile's report specs were not found: parsing broke?"
    bad = [part for spec in specs for part in spec.split(",") if not re.match(r"[a-z_]+=", part)]
    assert not bad, "Makefile: report --model parts that are not key=value (a comma in a caption?): " + "; ".join(bad)
