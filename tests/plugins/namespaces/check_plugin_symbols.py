#!/usr/bin/env python3
"""check_plugin_symbols.py PLUGINS_SRC_DIR 'obj1;obj2;...'

Every external, strongly defined symbol (nm types T D B R: the ones two objects cannot both define)
of an object compiled from plugins/<folder>/*.cpp must be in namespace locus::plugins::<folder>
(after vtable/typeinfo/guard-variable prefixes). Weak symbols (inline functions, templates) merge at
link time and are not checked. Prints every offending symbol with its object and exits 1 if any.
Objects from plugins/ itself (builtin.cpp, the generated list) are skipped.
"""
import os
import re
import subprocess
import sys

PREFIXES = ("vtable for ", "VTT for ", "construction vtable for ", "typeinfo for ", "typeinfo name for ",
            "guard variable for ", "non-virtual thunk to ", "virtual thunk to ", "covariant return thunk to ",
            "reference temporary #0 for ")


def main() -> int:
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    src = os.path.realpath(sys.argv[1])
    folders = sorted(d for d in os.listdir(src) if os.path.isdir(os.path.join(src, d)))
    objects = [o for o in sys.argv[2].split(";") if o]
    bad, checked = [], 0
    seen_folders = set()
    for obj in objects:
        # CMake puts plugins/<folder>/<file>.cpp's object at .../locus_builtins.dir/<folder>/<file>.cpp.o
        # (or, unity-built, the folder's batch at .../locus_builtins.dir/Unity/unity_<folder>_cxx.cxx.o).
        # Only the path below locus_builtins.dir names the folder: a build tree under a directory that
        # happens to share a plugin's name (a checkout in .../tum/build) must not count as that plugin.
        parts = [p for p in obj.replace("\\", "/").split("/") if p != "."]  # CMake writes .../locus_builtins.dir/./Unity/...
        if "locus_builtins.dir" not in parts:
            continue
        below = parts[len(parts) - 1 - parts[::-1].index("locus_builtins.dir") + 1:-1]
        folder = next((p for p in below if p in folders), None)
        # A unity build (LOCUS_UNITY_BUILD) batches each folder into .../Unity/unity_<folder>_cxx.cxx.o.
        unity = re.match(r"^unity_(.+)_cxx\.cxx\.o$", parts[-1]) if below == ["Unity"] else None
        if folder is None and unity and unity.group(1) in folders:
            folder = unity.group(1)
        if folder is None:
            continue
        seen_folders.add(folder)
        out = subprocess.run(["nm", "-C", "--defined-only", "-g", obj], check=True, capture_output=True, text=True).stdout
        want = f"locus::plugins::{folder}::"
        for line in out.splitlines():
            m = re.match(r"^[0-9a-fA-F]*\s+([A-Za-z])\s+(.*)$", line)
            if not m or m.group(1) not in "TDBR":
                continue
            name = m.group(2)
            for p in PREFIXES:
                if name.startswith(p):
                    name = name[len(p):]
                    break
            checked += 1
            if not name.startswith(want):
                bad.append(f"{os.path.relpath(obj)}: {m.group(2)}  (expected in {want[:-2]})")
    missing = [f for f in folders if f not in seen_folders]
    if missing:
        print("no object compiled from plugins/" + ", plugins/".join(missing) + " (wrong object list?)", file=sys.stderr)
        return 1
    if bad:
        print(f"{len(bad)} strong symbols outside their plugin's namespace:", file=sys.stderr)
        for b in bad:
            print("  " + b, file=sys.stderr)
        return 1
    print(f"OK: {checked} strong symbols in {len(seen_folders)} plugin folders, each in locus::plugins::<folder>")
    return 0


if __name__ == "__main__":
    sys.exit(main())
