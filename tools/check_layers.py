#!/usr/bin/env python3
"""Check that every #include runs down the documented layer order (docs/development.md, "Layout").

    python3 tools/check_layers.py [ROOT]

The rooms of src/uplvsm, lowest tier first:

    core | io, geometry | data | kernels | model, backbones | train, eval, render | uplvsm.h, study, serve | cli

A file may include its own room and the rooms of lower tiers, never a room of its own tier or above; kernels
includes core only (its ops sit below the model but need nothing of it); a public header (the rooms
cmake/install.cmake installs) includes no private one. The other C++ trees are held to the same rule: tests/<room>/
as their room (files directly in tests/ as core), bench/, python/src/ and fuzz/ above cli, examples/ above cli but
public rooms only. A test helper of another test folder ("train/train_test_util.h") counts as an include of that
room. Each file of src/uplvsm/<room>/ declares its code in namespace uplvsm::<room> (core's in uplvsm itself; nested
namespaces inside it are free), opening another room's namespace only to forward-declare. EXCEPTIONS lists the
includes allowed against the order, each with its reason; an exception that matches no
include is an error too, so the list cannot go stale. Exits 1 naming every offending include.
"""
import fnmatch
import pathlib
import re
import sys

TIERS = [["core"], ["io", "geometry"], ["data"], ["kernels"], ["model", "backbones"], ["train", "eval", "render"],
         ["uplvsm.h", "study", "serve"], ["cli"]]
TIER = {room: tier for tier, rooms in enumerate(TIERS) for room in rooms}
ONLY = {"kernels": {"core"}}  # rooms that may include no more than these
PUBLIC = {"core", "io", "geometry", "data", "model", "backbones", "eval", "render", "uplvsm.h"}
TOP = len(TIERS)  # bench, the Python module, fuzz targets, examples: above every room
TREES = ["src/uplvsm", "tests", "bench", "python/src", "fuzz", "examples"]

# (file pattern, include pattern, why): includes allowed against the order.
EXCEPTIONS = [
    ("tests/test_main.cpp", "uplvsm/kernels/ops.h", "every test binary prints which kernel paths it tests"),
    ("tests/*", "train/train_test_util.h",
     "the tests' shared fixtures (micro configs, synthetic rooms, a short training run) live beside the trainer's"),
    ("tests/kernels/*", "uplvsm/model/*", "the fused kernels are checked against the modules they serve"),
    ("tests/io/pretrained_weights_test.cpp", "uplvsm/model/*", "official weight files are read into the modules"),
    ("tests/io/image_test.cpp", "uplvsm/data/chunk_dataset.h", "a chunk's image bombs are refused at decode"),
    ("tests/core/retired_keys_test.cpp", "uplvsm/io/*", "a retired config key inside a stored checkpoint"),
    ("tests/geometry/plucker_test.cpp", "uplvsm/io/safetensors.h", "the official Plucker rays as a fixture"),
    ("tests/model/variants_test.cpp", "uplvsm/train/flops.h", "each variant's FLOP count against its forward"),
    ("tests/render/identity_trajectory_slow_test.cpp", "uplvsm/train/*", "trains the model the path renders"),
    ("tests/render/identity_trajectory_slow_test.cpp", "uplvsm/eval/*", "scores the rendered frames"),
    ("tests/train/gradient_difference_loss_test.cpp", "uplvsm/eval/*", "the loss against eval's gradient energy"),
]

INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')


def room_of_file(relative):
    """(room, tier) of a file given relative to the root; None for files outside the checked trees."""
    parts = relative.parts
    if parts[:2] == ("src", "uplvsm"):
        room = parts[2]  # a folder, or uplvsm.h itself
        return (room, TIER[room]) if room in TIER else None
    if parts[0] == "tests":
        if len(parts) == 2:
            return "core", TIER["core"]
        return (parts[1], TIER[parts[1]]) if parts[1] in TIER else None
    return (parts[0], TOP) if parts[0] in ("bench", "python", "fuzz", "examples") else None


def room_of_include(root, source, include):
    """The room an include names: uplvsm/<room>/..., the umbrella uplvsm/uplvsm.h, or a test helper tests/<room>/."""
    if include == "uplvsm/uplvsm.h":
        return "uplvsm.h"
    if include.startswith("uplvsm/"):
        room = include.split("/")[1]
        return room if room in TIER else None
    for base in (source.parent, root / "tests"):
        target = base / include
        if target.exists() and target.resolve().is_relative_to((root / "tests").resolve()):
            parts = target.resolve().relative_to((root / "tests").resolve()).parts
            return parts[0] if len(parts) > 1 and parts[0] in TIER else None
    return None


def offence(room, tier, included, relative):
    """Why including `included` from a file of `room` breaks the order, or None."""
    if included == room:
        return None
    if room in ONLY and included not in ONLY[room]:
        return f"{room} includes only {', '.join(sorted(ONLY[room]))}"
    if TIER[included] >= tier:
        return f"{included} is not below {room}"
    public_header = room in PUBLIC and relative.suffix == ".h" and relative.parts[0] == "src"
    if (public_header or room == "examples") and included not in PUBLIC:
        return f"{included} is private, {relative} is public"
    return None


NAMESPACE_BLOCK = re.compile(r"^namespace (uplvsm(?:::\w+)*) \{\n(.*?)^\}  // namespace \1$", re.M | re.S)
FORWARD_DECLARATION = re.compile(r"^\s*((struct|class) \w+;|//.*)?$")


def namespace_offences(root):
    """Files of src/uplvsm whose code lives in another room's namespace than their folder's."""
    errors = []
    for path in sorted((pathlib.Path(root) / "src" / "uplvsm").rglob("*")):
        relative = path.relative_to(root)
        if path.suffix not in (".cpp", ".h") or len(relative.parts) < 4:
            continue
        room = relative.parts[2]
        own = "uplvsm" if room == "core" else f"uplvsm::{room}"
        for match in NAMESPACE_BLOCK.finditer(path.read_text(errors="replace")):
            name, body = match.groups()
            nested = name.startswith(own + "::") and (room != "core" or name.split("::")[1] not in TIER)
            forward_only = all(FORWARD_DECLARATION.match(line) for line in body.splitlines())
            if name != own and not nested and not forward_only:
                errors.append(f"{relative}: namespace {name} in {room}/ (its namespace is {own})")
    return errors


def check(root, exceptions=EXCEPTIONS):
    """Every include against the order, as 'file:line: include (why)' lines, then every unused exception."""
    root = pathlib.Path(root)
    errors, used = [], set()
    for tree in TREES:
        for path in sorted((root / tree).rglob("*")):
            if path.suffix not in (".cpp", ".h") or not path.is_file():
                continue
            relative = path.relative_to(root)
            owner = room_of_file(relative)
            if owner is None:
                continue
            for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
                match = INCLUDE.match(line)
                included = match and room_of_include(root, path, match.group(1))
                why = included and offence(*owner, included, relative)
                if not why:
                    continue
                allowed = [i for i, (files, inc, _) in enumerate(exceptions)
                           if fnmatch.fnmatch(str(relative), files) and fnmatch.fnmatch(match.group(1), inc)]
                used.update(allowed)
                if not allowed:
                    errors.append(f"{relative}:{number}: #include \"{match.group(1)}\" ({why})")
    errors += namespace_offences(root)
    for i, (files, inc, _) in enumerate(exceptions):
        if i not in used:
            errors.append(f"tools/check_layers.py: exception ({files}, {inc}) matches no include: remove it")
    return errors


def main():
    root = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else pathlib.Path(__file__).resolve().parent.parent
    errors = check(root)
    for e in errors:
        print(e)
    if errors:
        print("check_layers: includes run up the layer order, or namespaces differ from folders (docs/development.md, "
              "\"Layout\")")
        return 1
    print("check_layers: every include runs down the layer order, every namespace is its folder's")
    return 0


if __name__ == "__main__":
    sys.exit(main())
