#!/usr/bin/env python3
"""Compares two diagnosis reports (JSON): the same keys, strings and numbers to 1e-9 relative.

Usage: scripts/compare_reports.py A.json B.json. The folder of each report is replaced by DIR
before comparing (log paths), and keys naming a time are skipped. Prints the differences."""
import json, sys
import re
na, nb = sys.argv[1].rsplit("/", 1)[0], sys.argv[2].rsplit("/", 1)[0]
a = json.loads(open(sys.argv[1]).read().replace(na, "DIR")); b = json.loads(open(sys.argv[2]).read().replace(nb, "DIR"))
bad = []
def walk(x, y, p):
    if any(k in p for k in ("time", "elapsed", "seconds_wall")): return
    if isinstance(x, dict):
        if not isinstance(y, dict) or set(x) != set(y): bad.append((p, "keys")); return
        for k in x: walk(x[k], y[k], p + "." + k)
    elif isinstance(x, list):
        if not isinstance(y, list) or len(x) != len(y): bad.append((p, "len")); return
        for i, (u, v) in enumerate(zip(x, y)): walk(u, v, p + f"[{i}]")
    elif isinstance(x, float) and isinstance(y, (int, float)):
        if x != y and abs(x - y) > 1e-9 * max(abs(x), abs(y)): bad.append((p, x, y))
    elif x != y: bad.append((p, x, y))
walk(a, b, "")
print(len(bad), "differences"); [print(d) for d in bad[:20]]
