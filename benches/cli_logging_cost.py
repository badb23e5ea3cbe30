"""The logging cost as `simgap simulate` pays it: the wall and CPU time (user + system) of
`simgap simulate --duration D` without and with `--out` (an MCAP log by default), run in turn
(unlogged, logged) for every binary given, so that all see the same machine load; medians.

    python3 benches/cli_logging_cost.py RUNS BIN [BIN...]      # env: DURATION (300), OUT (a .mcap path)

e.g. `python3 benches/cli_logging_cost.py 21 target/release/simgap` (docs/guide/logs.md).
"""

import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time


def main() -> None:
    runs, bins = int(sys.argv[1]), sys.argv[2:]
    duration = os.environ.get("DURATION", "300")
    out = os.environ.get("OUT") or os.path.join(tempfile.gettempdir(), f"simgap-logging-cost-{os.getpid()}.mcap")
    res = {(b, logged): ([], []) for b in bins for logged in (False, True)}
    for _ in range(runs):
        for b in bins:
            for logged in (False, True):
                args = [b, "simulate", "--duration", duration] + (["--out", out] if logged else [])
                r0, t0 = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
                subprocess.run(args, stdout=subprocess.DEVNULL, check=True)
                t1, r1 = time.perf_counter(), resource.getrusage(resource.RUSAGE_CHILDREN)
                res[(b, logged)][0].append(t1 - t0)
                res[(b, logged)][1].append(r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime)
    if os.path.exists(out) and not os.environ.get("OUT"):
        os.remove(out)
    for b in bins:
        wu, cu = (statistics.median(x) * 1e3 for x in res[(b, False)])
        wl, cl = (statistics.median(x) * 1e3 for x in res[(b, True)])
        print(f"{b}: wall {wu:.1f} -> {wl:.1f} ms ({wl / wu:.2f}x), cpu {cu:.1f} -> {cl:.1f} ms ({cl / cu:.2f}x); medians of {runs}, interleaved")


if __name__ == "__main__":
    main()
