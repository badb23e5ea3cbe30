"""A synthetic fleet diagnosed on a LocalCluster: ``python -m simgap.fleet.example``.

Six paper arms recorded on five days (two logs a day, one fitted, one held out): ``arm-01``'s elbow Coulomb friction
rises 10 % a day, ``arm-02`` carries a 1.5 kg payload from the third day, the others carry the
published friction with a 3 % spread between units. Prints the elbow's Coulomb friction per
robot and day, and the robots the fleet analysis flags.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import pandas as pd


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m simgap.fleet.example", description=__doc__.splitlines()[0])
    p.add_argument("--dir", type=Path, default=None, help="where to write the fleet's logs (default: a temporary folder)")
    p.add_argument("--workers", type=int, default=2, help="LocalCluster worker processes (default 2)")
    p.add_argument("--html", type=Path, default=None, help="also write the fleet report here")
    args = p.parse_args(argv)

    from simgap import fleet
    from simgap.fleet.synthetic import COULOMB_EFFECT, make_synthetic_fleet

    with tempfile.TemporaryDirectory() as tmp:
        root = args.dir or Path(tmp)
        synthetic = make_synthetic_fleet(root)  # 6 robots x 5 days, 3 MCAP logs each
        index = fleet.index_from_folder(root)  # the last log of each day (c-sine) is held out
        start = time.perf_counter()
        result = fleet.diagnose_fleet(index, synthetic.urdf, n_workers=args.workers)  # a LocalCluster
        wall = time.perf_counter() - start

        t = result.table
        fc = t[(t.effect == COULOMB_EFFECT) & (t.joint == "elbow")].pivot(index="robot", columns="day", values="value")
        with pd.option_context("display.width", 120, "display.precision", 3):
            print("elbow Coulomb friction fc [N·m] per robot and day")
            print(fc.to_string())
            print()
            flagged = result.findings()
            print(flagged[["robot", "finding", "effect", "joint", "parameter", "since"]].to_string(index=False))
            print()
            for r in flagged.itertuples(index=False):
                print(f"{r.robot}: {r.detail}")
        print(f"\n{len(result.tasks)} robot-days on {result.workers} workers in {wall:.0f} s")
        if args.html:
            result.to_html(args.html)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
