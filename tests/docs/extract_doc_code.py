#!/usr/bin/env python3
"""extract_doc_code.py DOC OUT_DIR AMIL_DIR

Keeps docs/writing-a-localizer.md true by turning it into code the build compiles:
  - every fenced block preceded by `<!-- file: PATH -->` is written to OUT_DIR/PATH (the `nearest`
    skeleton, plugins/nearest/*);
  - the shell block preceded by `<!-- recipe: copy -->` (copy plugins/amil, rename it to `x`) is run
    in OUT_DIR on a copy of AMIL_DIR with `x` spelled `amilcopy`, giving OUT_DIR/plugins/amilcopy/.
Errors name the doc and line. Run by tests/docs/CMakeLists.txt when the doc or plugins/amil change.
"""
import os
import re
import shutil
import subprocess
import sys

MARK = re.compile(r"^<!--\s*(file|recipe):\s*(\S+)\s*-->\s*$")


def blocks(doc_path):
    """Yields (kind, arg, code, line) for each marked fenced block."""
    lines = open(doc_path, encoding="utf-8").read().split("\n")
    i = 0
    while i < len(lines):
        m = MARK.match(lines[i])
        if not m:
            i += 1
            continue
        mark_line = i + 1
        j = i + 1
        while j < len(lines) and not lines[j].strip():
            j += 1
        if j >= len(lines) or not lines[j].startswith("```"):
            sys.exit(f"{doc_path}:{mark_line}: '{lines[i].strip()}' must be followed by a fenced code block")
        k = j + 1
        while k < len(lines) and not lines[k].startswith("```"):
            k += 1
        if k >= len(lines):
            sys.exit(f"{doc_path}:{j + 1}: unterminated code block")
        yield m.group(1), m.group(2), "\n".join(lines[j + 1:k]) + "\n", mark_line
        i = k + 1


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    doc, out, amil = sys.argv[1], os.path.abspath(sys.argv[2]), os.path.abspath(sys.argv[3])
    os.makedirs(out, exist_ok=True)
    recipes = 0
    for kind, arg, code, line in blocks(doc):
        if kind == "file":
            if os.path.isabs(arg) or ".." in arg.split("/"):
                sys.exit(f"{doc}:{line}: file path '{arg}' must be relative and stay inside the tree")
            path = os.path.join(out, arg)
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "w", encoding="utf-8") as f:
                f.write(code)
        elif arg == "copy":
            recipes += 1
            plugins = os.path.join(out, "plugins")
            for d in ("amil", "amilcopy"):
                shutil.rmtree(os.path.join(plugins, d), ignore_errors=True)
            shutil.copytree(amil, os.path.join(plugins, "amil"))
            script = re.sub(r"\bx\b", "amilcopy", code)
            r = subprocess.run(["bash", "-euo", "pipefail", "-c", script], cwd=out, capture_output=True, text=True)
            if r.returncode != 0:
                sys.exit(f"{doc}:{line}: the copy recipe failed (exit {r.returncode}):\n{script}\n{r.stdout}{r.stderr}")
            shutil.rmtree(os.path.join(plugins, "amil"))  # the original is the built-in one
        else:
            sys.exit(f"{doc}:{line}: unknown recipe '{arg}'")
    if recipes != 1:
        sys.exit(f"{doc}: expected one `<!-- recipe: copy -->` block, found {recipes}")


if __name__ == "__main__":
    main()
