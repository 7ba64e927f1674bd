#!/usr/bin/env python3
"""List C++ function definitions longer than N lines (issue 31: "no function over ~60 lines").

    python3 tools/function_lengths.py [-n 60] src/ python/src bench/

Prints `lines path:line name`, longest first, and always exits 0 (it measures, it does not gate).

A heuristic brace matcher, not a C++ parser: comments, string/char literals (raw strings included) and preprocessor
lines are blanked first, then every `{` is classified by the text before it (since the last `;`, `{` or `}`):
namespace / extern "C" (transparent), class/struct/union/enum (its inline member functions are counted), a function
body (the header has a parameter list), or anything else (initialisers, blocks). Lambdas and nested blocks inside a
function are counted within that function. A function's length runs from the line of its name to its closing brace.
"""
import argparse
import os
import re
import signal
import sys

EXTENSIONS = (".cpp", ".cc", ".cxx", ".h", ".hpp", ".hh", ".cu", ".cuh")


def quoted_end(text, i):
    """The index just past the literal opened by the quote at text[i] (escapes skipped; ends at a newline)."""
    j, n = i + 1, len(text)
    while j < n and text[j] != text[i] and text[j] != "\n":
        j += 2 if text[j] == "\\" else 1
    return min(n, j + 1)


def blank(text):
    """Returns `text` with comments, literals and preprocessor lines replaced by spaces (newlines kept)."""
    out = list(text)
    i, n = 0, len(text)
    line_start = True

    def wipe(a, b):
        for k in range(a, b):
            if out[k] != "\n":
                out[k] = " "

    while i < n:
        c = text[i]
        if line_start and c == "#":
            # A preprocessor directive, with its backslash continuations.
            j = i
            while j < n and not (text[j] == "\n" and text[j - 1] != "\\"):
                j += 1
            wipe(i, j)
            i = j
            continue
        if c == "\n":
            line_start = True
            i += 1
            continue
        if not c.isspace():
            line_start = False
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            wipe(i, j)
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            wipe(i, j)
            i = j
        elif c == '"':
            m = re.match(r'"([^()\\\s]{0,16})\(', text[i:]) if i >= 1 and text[i - 1] == "R" else None
            if m:
                close = ")" + m.group(1) + '"'
                j = text.find(close, i + len(m.group(0)))
                j = n if j < 0 else j + len(close)
            else:
                j = quoted_end(text, i)
            wipe(i + 1, j - 1)
            i = j
        elif c == "'":
            # A digit separator (1'000'000) when the token before it is a number; otherwise a character literal.
            k = i
            while k > 0 and (text[k - 1].isalnum() or text[k - 1] in "_.'"):
                k -= 1
            if k < i and text[k].isdigit():
                i += 1
                continue
            j = quoted_end(text, i)
            wipe(i + 1, j - 1)
            i = j
        else:
            i += 1
    return "".join(out)


def strip_template(header):
    """Drops leading `template <...>` clauses (balanced angle brackets)."""
    h = header.lstrip()
    while h.startswith("template"):
        k = h.find("<")
        if k < 0:
            break
        depth, j = 0, k
        while j < len(h):
            depth += {"<": 1, ">": -1}.get(h[j], 0)
            if depth == 0:
                break
            j += 1
        h = h[j + 1:].lstrip()
    return h


def first_paren_outside_angles(h):
    """The first `(` not inside template arguments (`std::function<R(A)> f(...)` is named f), or -1."""
    depth = 0
    for i, ch in enumerate(h):
        if ch == "<" and not h[:i].rstrip().endswith("operator"):
            depth += 1
        elif ch == ">" and depth > 0 and h[i - 1:i] != "-":
            depth -= 1
        elif ch == "(" and depth == 0:
            return i
    return -1


NAME_BEFORE_PAREN = re.compile(r"((?:[\w~]+(?:<[^<>()]*>)?\s*::\s*)*(?:operator\s*(?:\(\s*\)|[^\s(]+)|~?\w+))\s*$")


def function_name(header):
    """The (qualified) name before the parameter list, or None when the header is not a function's."""
    h = strip_template(header)
    m = re.search(r"\boperator\s*\(\s*\)\s*\(", h)
    paren = m.end() - 1 if m else first_paren_outside_angles(h)
    if paren < 0:
        return None, -1
    before = h[:paren]
    op = re.search(r"\boperator\b", before)
    if "=" in before and not op:
        return None, -1  # a variable initialised with a lambda or a call
    nm = NAME_BEFORE_PAREN.search(before)
    if not nm:
        return None, -1
    name = re.sub(r"\s+", "", nm.group(1))
    if re.fullmatch(r"[A-Z0-9_]+", name):
        # A macro such as TEST(Suite, Name) or PYBIND11_MODULE(name, m): its arguments are the name.
        close = h.find(")", paren)
        name = name + re.sub(r"\s+", " ", h[paren:close + 1])
    if name in ("if", "for", "while", "switch", "catch", "return", "sizeof", "decltype", "alignas"):
        return None, -1
    offset = len(header) - len(h) + nm.start(1)
    return name, offset


def functions(path):
    with open(path, encoding="utf-8", errors="replace") as f:
        code = blank(f.read())
    line_of = []
    line = 1
    for ch in code:
        line_of.append(line)
        if ch == "\n":
            line += 1
    results = []
    # Stack entries: (kind, start_index, name, name_line). Kinds: ns, class, func, block, hdr (a brace inside a
    # header: default argument `= {}` or a constructor initialiser `a_{x}`; closing it does not end the header).
    stack = []
    header_start = 0
    paren = 0
    for i, ch in enumerate(code):
        top = stack[-1][0] if stack else "ns"
        if ch == "(":
            paren += 1
        elif ch == ")":
            paren = max(0, paren - 1)
        elif ch == ";" and top in ("ns", "class"):
            header_start, paren = i + 1, 0
        elif ch == "{":
            if top in ("func", "block"):
                stack.append(("block", i, None, 0))
                continue
            header = code[header_start:i]
            prev = header.rstrip()[-1:] if header.strip() else ""
            ctor_init = re.search(r"\)\s*(?:noexcept\s*)?:(?!:)", header)
            if top == "hdr" or paren > 0 or (ctor_init and (prev.isalnum() or prev in "_>")):
                stack.append(("hdr", i, None, 0))
                continue
            body = strip_template(header)
            if re.search(r"\bnamespace\b", header) or re.fullmatch(r'\s*extern\s*"\s*"\s*', header):
                kind, name, name_line = "ns", None, 0
            elif re.match(r"(?:\w+\s+)*?(?:class|struct|union|enum)\b", body.split("(")[0].strip()) and (
                    "(" not in body or re.match(r"\s*(?:class|struct|union|enum)\b", body)):
                kind, name, name_line = "class", None, 0
            else:
                name, offset = function_name(header)
                if name:
                    name_at = header_start + offset + len(header[offset:]) - len(header[offset:].lstrip())
                    kind, name_line = "func", line_of[name_at]
                else:
                    kind, name_line = "block", 0
            stack.append((kind, i, name, name_line))
            header_start, paren = i + 1, 0
        elif ch == "}":
            if not stack:
                header_start, paren = i + 1, 0
                continue
            kind, start, name, name_line = stack.pop()
            if kind == "hdr":
                continue
            if kind == "func" and (not stack or stack[-1][0] in ("ns", "class")):
                results.append((line_of[i] - name_line + 1, name_line, name))
            if not stack or stack[-1][0] in ("ns", "class"):
                header_start, paren = i + 1, 0
    return results


def source_files(roots):
    for root in roots:
        if os.path.isfile(root):
            yield root
            continue
        for dirpath, dirnames, filenames in os.walk(root):
            dirnames.sort()
            for fn in sorted(filenames):
                if fn.endswith(EXTENSIONS):
                    yield os.path.join(dirpath, fn)


def main():
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)  # `| head` ends the listing quietly
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-n", "--min-lines", type=int, default=60, help="list functions longer than this (default 60)")
    parser.add_argument("paths", nargs="*", default=["src"], help="directories or files to scan (default src)")
    args = parser.parse_args()
    rows = []
    for path in source_files(args.paths):
        for length, line, name in functions(path):
            if length > args.min_lines:
                rows.append((length, os.path.normpath(path), line, name))
    rows.sort(key=lambda r: (-r[0], r[1], r[2]))
    for length, path, line, name in rows:
        print(f"{length} {path}:{line} {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
