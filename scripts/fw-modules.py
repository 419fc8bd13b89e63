#!/usr/bin/env python3
"""The firmware's modules form no circle: no two of them import each other, directly or
through others. Reads `crate::<module>` in the code (not in comments) of firmware/src/*.rs
and fails naming a cycle if there is one."""
import pathlib, re, sys

src = pathlib.Path(__file__).resolve().parent.parent / "firmware" / "src"
mods = {p.stem for p in src.glob("*.rs")}
deps = {}
for p in src.glob("*.rs"):
    code = "\n".join(l for l in p.read_text().splitlines() if not l.lstrip().startswith("//"))
    deps[p.stem] = sorted({m for m in re.findall(r"crate::([a-z_0-9]+)", code) if m in mods and m != p.stem})

state = {}
def visit(m, path):
    state[m] = "open"
    for d in deps.get(m, []):
        if state.get(d) == "open":
            cyc = path[path.index(d):] + [d]
            sys.exit("firmware module cycle: " + " -> ".join(cyc))
        if d not in state:
            visit(d, path + [d])
    state[m] = "done"

for m in sorted(mods):
    if m not in state:
        visit(m, [m])
leaves = sorted(m for m in mods if not deps[m])
print(f"firmware modules: {len(mods)}, no cycle; leaves: {', '.join(leaves)}")
