#!/usr/bin/env python3
"""Check that fuzz/CMakeLists.txt's READER_SOURCES lists every source a listed reader needs at link time.

    python3 tools/check_fuzz_sources.py

The fuzz build compiles its own short list of sources (with sanitizers), so a function moved out of a listed file into
a new one links in the main build and fails only in `make fuzz` (core/config_validation.cpp did, data/stored_scene.cpp
did). The rules, heuristics: a source implements the header of its own name, or else the first header of its own
directory it includes; every source that implements the header of a listed source must be listed too, and so must the
source of the same name as any project header a listed source includes (directly or through other project headers).
Exits 1 naming what is missing.
"""
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
SRC = ROOT / "src" / "uplvsm"


def reader_sources():
    text = (ROOT / "fuzz" / "CMakeLists.txt").read_text()
    match = re.search(r"set\(READER_SOURCES(.*?)\)", text, re.S)
    if not match:
        sys.exit("check_fuzz_sources: fuzz/CMakeLists.txt has no set(READER_SOURCES ...)")
    return set(match.group(1).split())


def implemented_header(source):
    """The header a source file implements: its own name's, else the first include from its own directory."""
    relative = source.relative_to(SRC)
    own = relative.with_suffix(".h")
    if (SRC / own).exists():
        return str(own)
    for line in source.read_text().splitlines():
        match = re.match(r'#include "uplvsm/([^"]+\.h)"', line)
        if match and pathlib.PurePath(match.group(1)).parent == relative.parent:
            return match.group(1)
    return None


def project_includes(relative):
    """The project headers a file includes, directly or through other project headers."""
    seen, todo = set(), [relative]
    while todo:
        for header in re.findall(r'#include "uplvsm/([^"]+\.h)"', (SRC / todo.pop()).read_text()):
            if header not in seen and (SRC / header).exists():
                seen.add(header)
                todo.append(header)
    return seen


def main():
    readers = reader_sources()
    implementers = {}
    for source in SRC.rglob("*.cpp"):
        implementers.setdefault(implemented_header(source), set()).add(str(source.relative_to(SRC)))
    missing = []
    for reader in sorted(readers):
        if not (SRC / reader).exists():
            missing.append(f"{reader} (listed, but src/uplvsm/{reader} does not exist)")
            continue
        header = implemented_header(SRC / reader)
        if header is None:  # no header of its own: nothing else can define what it declares
            continue
        for other in sorted(implementers.get(header, ())):
            if other not in readers:
                missing.append(f"{other} (implements uplvsm/{header}, as {reader} does)")
        for included in sorted(project_includes(reader)):
            source = str(pathlib.PurePath(included).with_suffix(".cpp"))
            if (SRC / source).exists() and source not in readers:
                missing.append(f"{source} (implements uplvsm/{included}, which {reader} includes)")
    for line in missing:
        print(f"check_fuzz_sources: fuzz/CMakeLists.txt READER_SOURCES lacks {line}")
    print(f"check_fuzz_sources: {len(readers)} reader sources, {len(missing)} missing")
    return 1 if missing else 0


if __name__ == "__main__":
    sys.exit(main())
