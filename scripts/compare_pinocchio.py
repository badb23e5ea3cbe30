#!/usr/bin/env python3
"""Per-call timings of simgap against Pinocchio on the same URDFs and the same states.

Run from the repository root (``make compare-pinocchio`` builds the example first)::

    .venv/bin/python scripts/compare_pinocchio.py [--count 1000] [--reps 21] [--json out.json]

For each robot (the paper arm, UR5 and the Panda with its fingers locked) it

1. builds the Pinocchio model from the URDF (``buildReducedModel`` locks the Panda's finger
   joints at zero, as simgap merges them into the hand when the chain ends at ``panda_hand``),
2. writes ``--count`` random states (q, qd, qdd, tau; seeded) to a CSV with columns
   ``q_<joint>``, ``qd_<joint>``, ``qdd_<joint>``, ``tau_<joint>``,
3. runs ``target/release/examples/timings`` on that URDF and CSV (simgap, native),
4. runs ``scripts/pinocchio_timings.cpp`` on the same model (saved with ``saveToBinary``) and
   CSV: Pinocchio, native, linked to the shipped ``libpinocchio_default``. It is compiled once
   into ``target/pinocchio-timings/`` when ``g++`` and Eigen 3.4 headers are found
   (``EIGEN_INCLUDE_DIR``, the cmeel prefix or ``/usr/include/eigen3``), else skipped,
5. times the same Pinocchio functions from Python (per call, including the Python call
   overhead, estimated separately on a one-joint model),

and prints a table of ratios simgap / Pinocchio (below 1: simgap faster), then the raw JSON.

The same is done for random chains of ``--chains`` joints (default 2, 4, 8, 16, 32, 64):
``timings --robot chainN --write-urdf`` writes ``Model::random_chain(N, 42 + N)`` as a URDF that
both libraries load (this is where ``forward_dynamics`` meets Pinocchio's ``aba`` on long chains).

Then the **batch** rows (``--batch-count`` states, default 100 000, of ``--batch-robots``,
default the Panda): simgap's Python batch call on the whole ``(N, dof)`` array, on
``--batch-threads`` threads (default 1: ``RAYON_NUM_THREADS``), against a Python loop over
Pinocchio's call(s) on the same states, same process; the speed-up is loop time / batch time.
Every figure is the median over ``--reps`` repetitions of one pass over all states, divided by
the number of states; the timers alternate for ``--rounds`` rounds and the fastest median is kept. On a shared machine absolute numbers are noisy; the ratios come from one
run in which both libraries see the same load.
"""

from __future__ import annotations

import argparse
import csv
import importlib.metadata
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
TIMINGS = ROOT / "target" / "release" / "examples" / "timings"
NATIVE_SRC = ROOT / "scripts" / "pinocchio_timings.cpp"
NATIVE_DIR = ROOT / "target" / "pinocchio-timings"

# (name, path in the example-robot-data robots dir or None for the paper arm, tip link, joints to lock)
ROBOTS = [
    ("paper_arm", None, None, []),
    ("ur5", "ur_description/urdf/ur5_robot.urdf", None, []),
    ("panda", "panda_description/urdf/panda.urdf", "panda_hand", ["panda_finger_joint1", "panda_finger_joint2"]),
]

# simgap function -> (native Pinocchio function, note)
PEERS = {
    "mass_matrix": ("crba", ""),
    "coriolis_matrix/euler_lagrange": ("computeCoriolisMatrix", ""),
    "coriolis_matrix/simplified": ("computeCoriolisMatrix", "Pinocchio has no simplified C"),
    "coriolis_torques": ("nonLinearEffects_zero_gravity", "nonLinearEffects on a zero-gravity copy"),
    "gravity_torques": ("computeGeneralizedGravity", ""),
    "mass_matrix_derivative": ("computeCoriolisMatrix", "Pinocchio has no Hdot; Hdot = C + C^T"),
    "bias_torques": ("nonLinearEffects", ""),
    "inverse_dynamics": ("rnea", ""),
    "forward_dynamics": ("aba", "ABA vs ours: ABA, or a two-joint arm's closed form"),
    "forward_dynamics_crba": ("aba", "our CRBA + Cholesky, whatever the size"),
    "forward_dynamics_aba": ("aba", "our ABA, whatever the size"),
    "dynamics_terms": ("crba+computeCoriolisMatrix+computeGeneralizedGravity", "one call vs Pinocchio's three"),
    "h_c_g_three_calls": ("crba+computeCoriolisMatrix+computeGeneralizedGravity", "three calls each"),
}


def robots_dir() -> Path | None:
    """The example-robot-data robots directory (SIMGAP_ROBOTS_DIR, the module, or the cmeel wheel)."""
    env = os.environ.get("SIMGAP_ROBOTS_DIR")
    if env:
        return Path(env) if Path(env).is_dir() else None
    try:
        import example_robot_data  # type: ignore[import-not-found]

        return Path(example_robot_data.getModelPath("ur_description/urdf/ur5_robot.urdf"))
    except ImportError:
        pass
    try:
        d = importlib.metadata.distribution("example-robot-data")
        p = Path(str(d.locate_file("cmeel.prefix/share/example-robot-data/robots")))
        return p if p.is_dir() else None
    except importlib.metadata.PackageNotFoundError:
        return None


def cmeel_prefix() -> Path | None:
    try:
        d = importlib.metadata.distribution("pin")
        p = Path(str(d.locate_file("cmeel.prefix")))
        return p if p.is_dir() else None
    except importlib.metadata.PackageNotFoundError:
        return None


def batch_timings(pin, model, urdf: Path, tip: str | None, states: dict[str, np.ndarray], reps: int, rounds: int) -> dict:
    """Per-state time of simgap's Python batch calls and of a Python loop over Pinocchio."""
    import simgap  # after RAYON_NUM_THREADS is set

    sm = simgap.Model.from_urdf(str(urdf), tip=tip)
    names = [j[0] for j in joint_layout(model)]
    if sm.joint_names != names:
        raise SystemExit(f"joint order differs: simgap {sm.joint_names}, Pinocchio {names}")
    data = pin.Data(model)
    q, qd, qdd, tau = (np.ascontiguousarray(states[k]) for k in ("angle", "qd", "qdd", "tau"))
    qs = [to_configuration(model, a) for a in q]
    vs, As, taus = list(qd), list(qdd), list(tau)
    idx = range(len(qs))

    def three(i):
        pin.crba(model, data, qs[i])
        pin.computeCoriolisMatrix(model, data, qs[i], vs[i])
        pin.computeGeneralizedGravity(model, data, qs[i])

    # simgap batch call, Pinocchio peer, Pinocchio loop
    rows = {
        "mass_matrix": (lambda: sm.mass_matrix(q), "crba", lambda: [pin.crba(model, data, qs[i]) for i in idx]),
        "coriolis_matrix": (lambda: sm.coriolis_matrix(q, qd), "computeCoriolisMatrix", lambda: [pin.computeCoriolisMatrix(model, data, qs[i], vs[i]) for i in idx]),
        "gravity_torques": (lambda: sm.gravity_torques(q), "computeGeneralizedGravity", lambda: [pin.computeGeneralizedGravity(model, data, qs[i]) for i in idx]),
        "bias_torques": (lambda: sm.bias_torques(q, qd), "nonLinearEffects", lambda: [pin.nonLinearEffects(model, data, qs[i], vs[i]) for i in idx]),
        "inverse_dynamics": (lambda: sm.inverse_dynamics(q, qd, qdd), "rnea", lambda: [pin.rnea(model, data, qs[i], vs[i], As[i]) for i in idx]),
        "forward_dynamics": (lambda: sm.forward_dynamics(q, qd, tau), "aba", lambda: [pin.aba(model, data, qs[i], vs[i], taus[i]) for i in idx]),
        "dynamics_terms": (lambda: sm.dynamics_terms(q, qd), "crba+computeCoriolisMatrix+computeGeneralizedGravity", lambda: [three(i) for i in idx]),
    }
    out = {}
    for name, (ours, peer, theirs) in rows.items():
        best_ours, best_theirs = float("inf"), float("inf")
        for _ in range(rounds):
            best_ours = min(best_ours, median_pass(ours, reps, len(qs)))
            best_theirs = min(best_theirs, median_pass(theirs, reps, len(qs)))
        out[name] = {"peer": peer, "simgap_batch_ns": best_ours, "pinocchio_loop_ns": best_theirs, "speedup": best_theirs / best_ours}
    # the batch H equals Pinocchio's (upper triangle) on a few states
    h = sm.mass_matrix(q[:50])
    hp = np.array([np.triu(pin.crba(model, data, x)) for x in qs[:50]])
    hp = hp + np.triu(hp, 1).transpose(0, 2, 1)
    out["max_abs_difference_of_mass_matrix"] = float(np.abs(h - hp).max())
    return out


def pinocchio_model(pin, urdf: Path, locked: list[str]):
    """Pinocchio model from the URDF, `locked` joints fixed at zero, gravity (0, 0, -9.81)."""
    model = pin.buildModelFromUrdf(str(urdf))
    if locked:
        ids = [model.getJointId(j) for j in locked]
        model = pin.buildReducedModel(model, ids, pin.neutral(model))
    model.gravity.linear = np.array([0.0, 0.0, -9.81])
    return model


def joint_layout(model):
    """(name, idx_q, nq, idx_v) of every movable joint, in Pinocchio order."""
    return [(model.names[j], model.joints[j].idx_q, model.joints[j].nq, model.joints[j].idx_v) for j in range(1, model.njoints)]


def random_states(model, count: int, seed: int) -> dict[str, np.ndarray]:
    """Angles (one per joint, in Pinocchio's joint order) within the limits or +-pi, qd, qdd, tau."""
    rng = np.random.default_rng(seed)
    n = model.nv
    lo = np.full(n, -np.pi)
    hi = np.full(n, np.pi)
    for k, (_, iq, nq, _) in enumerate(joint_layout(model)):
        if nq == 1 and np.isfinite(model.lowerPositionLimit[iq]) and model.upperPositionLimit[iq] > model.lowerPositionLimit[iq]:
            lo[k] = max(lo[k], model.lowerPositionLimit[iq])
            hi[k] = min(hi[k], model.upperPositionLimit[iq])
    return {
        "angle": rng.uniform(lo, hi, (count, n)),
        "qd": rng.uniform(-2.0, 2.0, (count, n)),
        "qdd": rng.uniform(-5.0, 5.0, (count, n)),
        "tau": rng.uniform(-20.0, 20.0, (count, n)),
    }


def to_configuration(model, angles: np.ndarray) -> np.ndarray:
    """Pinocchio configuration from one angle per joint ((cos, sin) for continuous joints)."""
    q = np.zeros(model.nq)
    for k, (_, iq, nq, _) in enumerate(joint_layout(model)):
        if nq == 1:
            q[iq] = angles[k]
        else:
            q[iq], q[iq + 1] = np.cos(angles[k]), np.sin(angles[k])
    return q


def write_states(path: Path, model, states: dict[str, np.ndarray]) -> None:
    names = [j[0] for j in joint_layout(model)]
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow([f"{p}_{n}" for p in ("q", "qd", "qdd", "tau") for n in names])
        for i in range(len(states["angle"])):
            w.writerow([repr(float(x)) for key in ("angle", "qd", "qdd", "tau") for x in states[key][i]])


def native_binary() -> tuple[Path | None, str]:
    """Compiles scripts/pinocchio_timings.cpp once (cached); (binary, message)."""
    prefix = cmeel_prefix()
    exe = NATIVE_DIR / "pinocchio_timings"
    if exe.exists() and exe.stat().st_mtime > NATIVE_SRC.stat().st_mtime:
        return exe, "cached"
    cxx = shutil.which("g++") or shutil.which("c++")
    if prefix is None or cxx is None:
        return None, "no C++ compiler or no Pinocchio cmeel prefix"
    eigen = [Path(p) for p in (os.environ.get("EIGEN_INCLUDE_DIR", ""), str(prefix / "include" / "eigen3"), "/usr/include/eigen3") if p]
    eigen = [p for p in eigen if (p / "Eigen" / "Core").exists()]
    if not eigen:
        return None, "Eigen headers not found (apt-get install libeigen3-dev, or set EIGEN_INCLUDE_DIR)"
    NATIVE_DIR.mkdir(parents=True, exist_ok=True)
    cmd = [
        cxx, "-std=c++17", "-O3", "-DNDEBUG",
        # the definitions Pinocchio's CMake config exports
        "-DBOOST_MPL_LIMIT_LIST_SIZE=30", "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30", "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS",
        "-DBOOST_FUSION_INVOKE_MAX_ARITY=12", "-DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION",
        f"-I{prefix / 'include'}", f"-I{eigen[0]}", str(NATIVE_SRC), "-o", str(exe),
        f"-L{prefix / 'lib'}", "-lpinocchio_default", "-lboost_serialization", f"-Wl,-rpath,{prefix / 'lib'}",
    ]
    print("compiling the native Pinocchio timer (a few minutes, once):", " ".join(cmd), file=sys.stderr)
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        return None, "compilation failed: " + r.stderr[-2000:]
    return exe, "compiled"


def python_timings(pin, model, states: dict[str, np.ndarray], reps: int) -> dict[str, float]:
    """Per-call time of Pinocchio's Python bindings, same median-of-passes method."""
    data = pin.Data(model)
    nog = model.copy()
    nog.gravity.linear = np.zeros(3)
    data_nog = pin.Data(nog)
    qs = [to_configuration(model, a) for a in states["angle"]]
    vs = [np.ascontiguousarray(v) for v in states["qd"]]
    As = [np.ascontiguousarray(a) for a in states["qdd"]]
    taus = [np.ascontiguousarray(t) for t in states["tau"]]
    idx = range(len(qs))

    def three(i):
        pin.crba(model, data, qs[i])
        pin.computeCoriolisMatrix(model, data, qs[i], vs[i])
        pin.computeGeneralizedGravity(model, data, qs[i])

    loops = {
        "crba": lambda: [pin.crba(model, data, qs[i]) for i in idx],
        "computeCoriolisMatrix": lambda: [pin.computeCoriolisMatrix(model, data, qs[i], vs[i]) for i in idx],
        "nonLinearEffects_zero_gravity": lambda: [pin.nonLinearEffects(nog, data_nog, qs[i], vs[i]) for i in idx],
        "computeGeneralizedGravity": lambda: [pin.computeGeneralizedGravity(model, data, qs[i]) for i in idx],
        "nonLinearEffects": lambda: [pin.nonLinearEffects(model, data, qs[i], vs[i]) for i in idx],
        "rnea": lambda: [pin.rnea(model, data, qs[i], vs[i], As[i]) for i in idx],
        "aba": lambda: [pin.aba(model, data, qs[i], vs[i], taus[i]) for i in idx],
        "crba+computeCoriolisMatrix+computeGeneralizedGravity": lambda: [three(i) for i in idx],
    }
    return {name: median_pass(loop, reps, len(qs)) for name, loop in loops.items()}


def median_pass(loop, reps: int, count: int) -> float:
    loop()  # untimed warm-up pass
    per_call = []
    for _ in range(reps):
        t0 = time.perf_counter_ns()
        loop()
        per_call.append((time.perf_counter_ns() - t0) / count)
    return statistics.median(per_call)


def python_overhead(pin, reps: int, count: int) -> float:
    """Per-call time of computeGeneralizedGravity on a one-joint model: almost only the cost of
    a Python call into Pinocchio (argument conversion, dispatch, result wrapping)."""
    m = pin.Model()
    j = m.addJoint(0, pin.JointModelRY(), pin.SE3.Identity(), "j")
    m.appendBodyToJoint(j, pin.Inertia.Random(), pin.SE3.Identity())
    d = pin.Data(m)
    qs = [np.array([x]) for x in np.linspace(-1, 1, count)]
    return median_pass(lambda: [pin.computeGeneralizedGravity(m, d, q) for q in qs], reps, count)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--count", type=int, default=1000, help="states per robot (default 1000)")
    ap.add_argument("--reps", type=int, default=21, help="timed passes, median reported (default 21)")
    ap.add_argument("--rounds", type=int, default=3, help="alternating rounds, fastest median kept (default 3)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", type=Path, help="also write the results here")
    ap.add_argument("--no-native", action="store_true", help="skip the native Pinocchio timer")
    ap.add_argument("--chains", default="2,4,8,16,32,64", help="random chain sizes, comma-separated ('' for none)")
    ap.add_argument("--batch-count", type=int, default=100_000, help="states of the batch rows (0: no batch rows)")
    ap.add_argument("--batch-robots", default="panda", help="robots of the batch rows, comma-separated")
    ap.add_argument("--batch-threads", type=int, default=1, help="threads of simgap's batch calls (RAYON_NUM_THREADS)")
    ap.add_argument("--batch-reps", type=int, default=3, help="timed passes of the batch rows, median reported")
    args = ap.parse_args()
    os.environ["RAYON_NUM_THREADS"] = str(args.batch_threads)

    try:
        import pinocchio as pin
    except ImportError:
        print("pinocchio is not importable: run `make venv` (pin==4.1.0) and use .venv/bin/python", file=sys.stderr)
        return 1
    if not TIMINGS.exists():
        print(f"{TIMINGS} missing: run `cargo build --release --example timings` first", file=sys.stderr)
        return 1
    rdir = robots_dir()
    native, native_msg = (None, "disabled by --no-native") if args.no_native else native_binary()
    if native is None:
        print(f"native Pinocchio timings skipped: {native_msg}", file=sys.stderr)

    overhead = python_overhead(pin, args.reps, args.count)
    results = {"pinocchio_version": pin.__version__, "count": args.count, "reps": args.reps, "rounds": args.rounds, "python_call_overhead_ns": overhead, "robots": {}}
    results["batch"] = {"count": args.batch_count, "threads": args.batch_threads, "reps": args.batch_reps, "robots": {}}
    with tempfile.TemporaryDirectory() as tmp:
        chains = [int(c) for c in args.chains.split(",") if c.strip()]
        robots = list(ROBOTS) + [(f"chain{n}", f"chain{n}", None, []) for n in chains]
        for name, rel, tip, locked in robots:
            if rel is None:
                urdf = ROOT / "crates" / "simgap-core" / "models" / "paper_arm.urdf"
            elif rel.startswith("chain"):
                urdf = Path(tmp) / f"{rel}.urdf"
                subprocess.run([str(TIMINGS), "--robot", rel, "--write-urdf", str(urdf)], check=True)
            elif rdir is None:
                print(f"skipping {name}: example-robot-data not found (make venv, or set SIMGAP_ROBOTS_DIR)", file=sys.stderr)
                continue
            else:
                urdf = rdir / rel
            model = pinocchio_model(pin, urdf, locked)
            states = random_states(model, args.count, args.seed)
            csv_path = Path(tmp) / f"{name}.csv"
            write_states(csv_path, model, states)
            cmd = [str(TIMINGS), "--urdf", str(urdf), "--name", name, "--states", str(csv_path), "--reps", str(args.reps)]
            if tip:
                cmd += ["--tip", tip]
            bin_path = Path(tmp) / f"{name}.bin"
            model.saveToBinary(str(bin_path))
            entry: dict = {"dof": model.nv}
            # alternate the timers for --rounds rounds, keeping each function's fastest median,
            # so that a burst of load on the shared machine hits both libraries alike
            for _ in range(args.rounds):
                simgap = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)["ns_per_call"]
                keep_min(entry, "simgap", simgap)
                if native is not None:
                    out = subprocess.run([str(native), str(bin_path), str(csv_path), str(args.reps), name], check=True, capture_output=True, text=True)
                    keep_min(entry, "pinocchio_native", json.loads(out.stdout)["ns_per_call"])
                keep_min(entry, "pinocchio_python", python_timings(pin, model, states, args.reps))
            results["robots"][name] = entry
            if args.batch_count > 0 and name in args.batch_robots.split(","):
                batch_states = random_states(model, args.batch_count, args.seed + 1)
                results["batch"]["robots"][name] = batch_timings(pin, model, urdf, tip, batch_states, args.batch_reps, args.rounds)

    print_table(results)
    print(json.dumps(results))
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


def keep_min(entry: dict, key: str, timings: dict[str, float]) -> None:
    old = entry.setdefault(key, {})
    for k, v in timings.items():
        old[k] = min(v, old.get(k, float("inf")))


def print_table(results) -> None:
    oh = results["python_call_overhead_ns"]
    print(f"# simgap vs Pinocchio {results['pinocchio_version']}: ns per call, median of {results['reps']} passes over {results['count']} states,")
    print(f"# fastest of {results['rounds']} alternating rounds")
    print("# ratio < 1: simgap faster. 'native' = Pinocchio's C++ (shipped libpinocchio_default) timed in a C++ loop;")
    print(f"# 'python' = Pinocchio called from Python, which adds ~{oh:.0f} ns of call overhead per call (measured on a 1-joint model);")
    print("# 'py-oh' subtracts that estimate. Shared machine: absolute numbers are noisy, ratios come from one run.")
    for robot, e in results["robots"].items():
        native = e.get("pinocchio_native")
        print(f"\n## {robot} ({e['dof']} dof)")
        print(f"{'simgap function':34s} {'simgap':>8s} {'pin native':>10s} {'ratio':>6s} {'pin python':>10s} {'ratio':>6s} {'py-oh':>6s}  peer")
        for fn, ns in e["simgap"].items():
            peer, note = PEERS.get(fn, ("", ""))
            py = e["pinocchio_python"].get(peer)
            nat = native.get(peer) if native else None
            if peer == "crba" and native:
                nat = min(native["crba"], native["crba_world"])  # the faster convention
            calls = 3 if peer.count("+") == 2 else 1
            cols = [f"{fn:34s}", f"{ns:8.0f}"]
            cols += [f"{nat:10.0f}", f"{ns / nat:6.2f}"] if nat else [f"{'-':>10s}", f"{'-':>6s}"]
            if py:
                # the overhead estimate is meaningless when it is most of the call
                rest = py - calls * oh
                cols += [f"{py:10.0f}", f"{ns / py:6.2f}", f"{ns / rest:6.2f}" if rest > 0.3 * py else f"{'n/a':>6s}"]
            else:
                cols += [f"{'-':>10s}", f"{'-':>6s}", f"{'-':>6s}"]
            print(" ".join(cols) + f"  {peer}" + (f" ({note})" if note else ""))
    batch = results.get("batch", {})
    for robot, rows in batch.get("robots", {}).items():
        print(f"\n## batch: {robot}, {batch['count']} states, simgap on {batch['threads']} thread(s), median of {batch['reps']} passes")
        print(f"{'simgap batch call':20s} {'simgap':>8s} {'pin loop':>9s} {'speed-up':>8s}  Python loop over")
        for fn, r in rows.items():
            if isinstance(r, dict):
                print(f"{fn:20s} {r['simgap_batch_ns']:8.0f} {r['pinocchio_loop_ns']:9.0f} {r['speedup']:7.1f}x  {r['peer']}")
        print(f"(max |H_simgap - H_pinocchio| over 50 states: {rows['max_abs_difference_of_mass_matrix']:.1e})")


if __name__ == "__main__":
    sys.exit(main())
