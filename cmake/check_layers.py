#!/usr/bin/env python3
"""Checks the dependency direction of docs/architecture.md against the code.

Reads the table of allowed dependencies from docs/architecture.md (the rows between the
"<!-- layers:begin -->" and "<!-- layers:end -->" markers: `| module | may depend on |`), then
every `#include "area/..."` in the sources and every msmcal_<module>... library named in the
CMakeLists.txt files under each module's folder. An edge from one module to another that the
table does not allow fails the check, with the file and line that makes it.

Usage: check_layers.py SOURCE_DIR   (exit status 0: every edge allowed; 1: violations listed)
"""
import os
import re
import sys

BEGIN, END = "<!-- layers:begin -->", "<!-- layers:end -->"
SOURCE_EXT = (".h", ".hpp", ".cc", ".cpp", ".c")


def read_table(doc):
    text = open(doc, encoding="utf-8").read()
    if BEGIN not in text or END not in text:
        sys.exit(f"{doc}: no table of allowed dependencies between {BEGIN} and {END}")
    allowed = {}
    for line in text.split(BEGIN, 1)[1].split(END, 1)[0].splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 2 or not cells[0] or set(cells[0]) <= set("-: "):
            continue
        module = cells[0].strip("`")
        if module == "module":
            continue
        deps = {d.strip().strip("`") for d in cells[1].split(",")}
        allowed[module] = {d for d in deps if d and d not in ("-", "—", "nothing")}
    if not allowed:
        sys.exit(f"{doc}: the table of allowed dependencies is empty")
    for module, deps in allowed.items():
        unknown = deps - set(allowed)
        if unknown:
            sys.exit(f"{doc}: {module} may depend on unknown module(s) {sorted(unknown)}")
    return allowed


def edges(root, modules):
    include = re.compile(r'^\s*#\s*include\s+"([^"/]+)/')
    library = re.compile(r"\bmsmcal_(" + "|".join(map(re.escape, modules)) + r")(?:_\w+)?\b")
    comment = re.compile(r"#.*$")
    for module in modules:
        top = os.path.join(root, module)
        if not os.path.isdir(top):
            yield module, None, os.path.relpath(top, root), 0, "listed module has no folder"
            continue
        for folder, dirs, files in os.walk(top):
            dirs.sort()
            for name in sorted(files):
                path = os.path.join(folder, name)
                rel = os.path.relpath(path, root)
                if name.endswith(SOURCE_EXT):
                    with open(path, encoding="utf-8", errors="replace") as f:
                        for n, line in enumerate(f, 1):
                            m = include.match(line)
                            if m and m.group(1) in modules and m.group(1) != module:
                                yield module, m.group(1), rel, n, line.strip()
                elif name == "CMakeLists.txt" or name.endswith(".cmake"):
                    with open(path, encoding="utf-8") as f:
                        for n, line in enumerate(f, 1):
                            code = comment.sub("", line)
                            for m in library.finditer(code):
                                if m.group(1) != module:
                                    yield module, m.group(1), rel, n, m.group(0)


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    root = sys.argv[1]
    doc = os.path.join(root, "docs", "architecture.md")
    allowed = read_table(doc)
    bad = []
    count = 0
    for module, dep, rel, n, what in edges(root, list(allowed)):
        count += 1
        if dep is None:
            bad.append(f"{rel}: {what}")
        elif dep not in allowed[module]:
            bad.append(f"{rel}:{n}: {module} -> {dep} ({what}) is against the direction of "
                       f"docs/architecture.md ({module} may depend on: "
                       f"{', '.join(sorted(allowed[module])) or 'nothing'})")
    for b in bad:
        print(b)
    if bad:
        print(f"{len(bad)} dependency edge(s) against docs/architecture.md")
        return 1
    print(f"{count} cross-module edges checked against docs/architecture.md: all allowed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
