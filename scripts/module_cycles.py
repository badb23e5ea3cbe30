#!/usr/bin/env python3
"""Import circles among the modules of one crate.

Reads every `.rs` file under SRC (default crates/simgap-core/src) and takes every `crate::a::b`
path outside comments (`use` lines and paths written inline alike). Each path goes to the
module file that defines it: the longest prefix of the path that is a module, an item
re-exported at the crate root to the module it comes from. Prints the strongly connected
components of more than one file of that graph (and exits 1), or `no import circle` (and
exits 0). lib.rs's own `mod` and `pub use` lines are left out: the root declares and
re-exports every module by design.

    python3 scripts/module_cycles.py [SRC]
"""
import os
import re
import sys


def module_of(path, src):
    rel = os.path.relpath(path, src)[:-3].split(os.sep)
    if rel[-1] in ("lib", "mod"):
        rel = rel[:-1]
    return tuple(rel)


def paths_in(line):
    """`crate::` paths of one line; `use crate::a::{b, c::d}` gives a::b and a::c::d."""
    out = []
    for m in re.finditer(r"crate::([A-Za-z0-9_:]*)(\{[^}]*\})?", line):
        head = [p for p in m.group(1).split("::") if p]
        if m.group(2):
            for item in m.group(2)[1:-1].split(","):
                item = item.strip().split(" as ")[0]
                if item and item != "self":
                    out.append(head + [p for p in item.split("::") if p])
                elif item == "self":
                    out.append(head)
        else:
            out.append(head)
    return out


def main():
    src = sys.argv[1] if len(sys.argv) > 1 else "crates/simgap-core/src"
    files = {}
    for root, _, names in os.walk(src):
        for n in names:
            if n.endswith(".rs"):
                p = os.path.join(root, n)
                files[module_of(p, src)] = p
    # items re-exported at the crate root, by name: the module that defines them
    reexports = {}
    with open(files[()], encoding="utf-8") as f:
        root = re.sub(r"//[^\n]*", "", f.read())
    for m in re.finditer(r"pub use ([A-Za-z0-9_:]+?)::(?:\{([^}]*)\}|([A-Za-z0-9_]+));", root):
        for item in (m.group(2) or m.group(3)).split(","):
            item = item.strip().split(" as ")[-1]
            if item:
                reexports[item] = tuple(m.group(1).split("::"))
    edges = {m: set() for m in files}
    for mod, path in files.items():
        if mod == ():
            continue
        with open(path, encoding="utf-8") as f:
            for line in f:
                code = line.split("//", 1)[0]
                for segs in paths_in(code):
                    if segs and segs[0] in reexports:
                        segs = list(reexports[segs[0]]) + segs[1:]
                    # the longest prefix that is a module file
                    target = ()
                    for k in range(len(segs), 0, -1):
                        if tuple(segs[:k]) in files:
                            target = tuple(segs[:k])
                            break
                    if target != mod:
                        edges[mod].add(target)
    # Tarjan's strongly connected components
    index, low, on, stack, comps, counter = {}, {}, set(), [], [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            comps.append(comp)

    sys.setrecursionlimit(10000)
    for v in sorted(edges):
        if v not in index:
            visit(v)
    name = lambda m: os.path.relpath(files[m], src)
    circles = [sorted(name(m) for m in c) for c in comps if len(c) > 1]
    n_edges = sum(len(e) for e in edges.values())
    print(f"{len(files)} module files, {n_edges} imports between them")
    if not circles:
        print("no import circle")
        return 0
    for c in circles:
        print(f"import circle of {len(c)} files: {', '.join(c)}")
    for c in comps:
        if len(c) > 1:
            members = set(c)
            for m in sorted(c):
                inner = sorted(name(t) for t in edges[m] if t in members)
                print(f"  {name(m)} -> {', '.join(inner)}")
    return 1


if __name__ == "__main__":
    sys.exit(main())
