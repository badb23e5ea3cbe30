"""Batch dynamics from numpy: simgap's batch calls vs a Python loop over Pinocchio, same states.

Run (after `make python-package`):

    .venv/bin/python python/examples/bench_batch.py [--states 100000] [--repeat 3]

Both sides see the same 100 000 seeded random Panda states (fingers locked: simgap
`tip="panda_hand"`, Pinocchio `buildReducedModel` with the finger joints at 0) and store every
result in a preallocated array. Pinocchio's `crba` fills only the upper triangle of H; the
loop does not symmetrise it (in Pinocchio's favour). Times are the best of `--repeat` runs.
"""

from __future__ import annotations

import argparse
import os
import platform
import site
import sys
import time
from pathlib import Path

import numpy as np

import simgap


def panda_urdf() -> Path:
    for base in [*site.getsitepackages(), site.getusersitepackages()]:
        p = Path(base) / "cmeel.prefix" / "share" / "example-robot-data" / "robots" / "panda_description" / "urdf" / "panda.urdf"
        if p.is_file():
            return p
    sys.exit("example-robot-data is not installed (pip install example-robot-data)")


def best_of(repeat: int, f) -> float:  # noqa: ANN001
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--states", type=int, default=100_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    import pinocchio as pin

    urdf = panda_urdf()
    ours = simgap.Model.from_urdf(urdf, tip="panda_hand")
    full = pin.buildModelFromUrdf(str(urdf))
    locked = [full.getJointId(f"panda_finger_joint{i}") for i in (1, 2)]
    theirs = pin.buildReducedModel(full, locked, np.zeros(full.nq))
    data = theirs.createData()
    n, dof = args.states, ours.dof
    rng = np.random.default_rng(0)
    q = rng.uniform(-np.pi, np.pi, size=(n, dof))
    qd = rng.normal(size=(n, dof))

    # pinocchio: a Python loop, one call per term per state
    def pin_mass_matrix() -> None:
        out = np.empty((n, dof, dof))
        for k in range(n):
            out[k] = pin.crba(theirs, data, q[k])

    def pin_terms() -> None:
        h, c, g = np.empty((n, dof, dof)), np.empty((n, dof, dof)), np.empty((n, dof))
        for k in range(n):
            h[k] = pin.crba(theirs, data, q[k])
            c[k] = pin.computeCoriolisMatrix(theirs, data, q[k], qd[k])
            g[k] = pin.computeGeneralizedGravity(theirs, data, q[k])

    # simgap: one call per term per state, and one batch call
    def loop_mass_matrix() -> None:
        out = np.empty((n, dof, dof))
        for k in range(n):
            out[k] = ours.mass_matrix(q[k])

    def loop_terms() -> None:
        h, c, g = np.empty((n, dof, dof)), np.empty((n, dof, dof)), np.empty((n, dof))
        for k in range(n):
            h[k], c[k], g[k] = ours.dynamics_terms(q[k], qd[k])

    rows = [
        ("mass_matrix", "Pinocchio loop (crba)", best_of(args.repeat, pin_mass_matrix)),
        ("mass_matrix", "simgap loop", best_of(args.repeat, loop_mass_matrix)),
        ("mass_matrix", "simgap batch", best_of(args.repeat, lambda: ours.mass_matrix(q))),
        ("dynamics_terms", "Pinocchio loop (crba + C + g)", best_of(args.repeat, pin_terms)),
        ("dynamics_terms", "simgap loop", best_of(args.repeat, loop_terms)),
        ("dynamics_terms", "simgap batch", best_of(args.repeat, lambda: ours.dynamics_terms(q, qd))),
    ]

    load = ", load average {:.1f} {:.1f} {:.1f}".format(*os.getloadavg()) if hasattr(os, "getloadavg") else ""
    threads = os.environ.get("RAYON_NUM_THREADS", "all")
    print(f"Panda 7-DOF, {n} random states, best of {args.repeat}; {os.cpu_count()} logical cores ({threads} used by simgap){load}; {platform.machine()}")
    print(f"Python {platform.python_version()}, numpy {np.__version__}, pinocchio {pin.__version__}, simgap {simgap.__version__}")
    print()
    print(f"| {'quantity':<15}| {'method':<30}| {'total [ms]':>10} | {'per state [µs]':>14} | {'vs Pinocchio loop':>17} |")
    print(f"|{'-' * 16}|{'-' * 31}|{'-' * 12}|{'-' * 16}|{'-' * 19}|")
    for quantity, method, seconds in rows:
        reference = next(s for qn, m, s in rows if qn == quantity and m.startswith("Pinocchio"))
        print(f"| {quantity:<15}| {method:<30}| {seconds * 1e3:>10.1f} | {seconds / n * 1e6:>14.3f} | {reference / seconds:>16.1f}x |")


if __name__ == "__main__":
    main()
