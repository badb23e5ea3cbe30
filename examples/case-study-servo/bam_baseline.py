#!/usr/bin/env python3
"""BAM's fitted XL330 models as comparison baselines on the Rhoban pendulum logs.

Usage (from the repository root)::

    python3 examples/case-study-servo/bam_baseline.py --data ../shared/data/rhoban-bam-xl330 \
        --out-json /tmp/bam-baseline.json --out-md /tmp/bam-baseline.md \
        [--logs NAME,NAME] [--params FILE ...] [--holdout NAME,NAME]
        [--windows windows.json] [--every 0.1] [--velocity fit|central|speed]
        [--horizons 0.1,0.25,0.5] [--vin nominal|logged]

For every raw log (or the ``--logs`` given) and every BAM parameter file (default: the
published m1–m6 and the xl330 branch's m1, m2, m6; the error gain each file was fitted with,
see ``bam_models.error_gain_for``), it computes:

(a) **BAM's own measure** (``bam/mae.py``): the mean absolute position error of one rollout
    of the whole run, from the first sample's position and speed, with the control simulated
    from the simulated position (``rollout_log(simulate_control=True)``), on BAM's 5 ms resample
    of the raw log (``bam/process.py``; ``mae.py`` is run on a folder of those), every
    resampled sample counted, torque on and off. Pooled: the mean of the per-log MAEs, as
    ``mae.py`` prints. (``mae_raw``: the same rollout on the raw, non-uniform stamps.)
(b) **k-step prediction error**: the RMS, over windows, of the position error at t0 + h for
    h in ``--horizons``, each window restarting the model from a given state (q0, q̇0) at t0
    and driving it with the logged goal and torque enable (control simulated), on the raw
    timeline. Pooled: the RMS over all windows of the ``--holdout`` runs.
(c) **constant-velocity floor** on the same windows: q0 + q̇0 h against the log.

Windows. By default one window every ``--every`` s: t0 = the first stamp at or after each
multiple of 0.1 s, q0 = the logged position there, q̇0 = the slope at t0 of a quadratic fitted
to the 7 stamps around it (``--velocity fit``; ``central``: a central difference; ``speed``:
the servo's speed register). ``--windows FILE`` replaces them with the windows simgap uses:
``{"runs": [{"source": "NAME.csv", "windows": [{"t0": s, "q0": [rad], "qd0": [rad/s]}]}]}``
(t0 on the CSV's time axis, which starts at the log's first stamp; one joint, so q0 and qd0 hold
one number each). :func:`evaluate` takes the same windows as a Python mapping
``{name: [(t0, q0, qd0), ...]}``.

Voltage. BAM drives its model with the nominal ``vin`` of the log (7.4 V); so do we by
default. ``--vin logged`` uses the logged input voltage per sample (our variant).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bam_models import bam_mae, kstep, load_params, param_files, raw_mae  # noqa: E402
from bam_to_simgap import default_data_dir, load_raw, raw_logs  # noqa: E402

HORIZONS = (0.1, 0.25, 0.5)


def velocity_at(t: np.ndarray, q: np.ndarray, i: int, method: str = "fit", qd_register=None, half: int = 3) -> float:
    """An estimate of q̇ at sample i from the logged positions (or the speed register)."""
    n = len(t)
    if method == "speed":
        return float(qd_register[i])
    if method == "central":
        a, b = max(i - 1, 0), min(i + 1, n - 1)
        return float((q[b] - q[a]) / (t[b] - t[a]))
    if method != "fit":
        raise ValueError(f"unknown velocity method {method!r} (fit, central, speed)")
    a, b = max(i - half, 0), min(i + half, n - 1)
    tt = t[a : b + 1] - t[i]
    c = np.polyfit(tt, q[a : b + 1], 2)
    return float(c[1])


def default_windows(raw: dict, every: float = 0.1, velocity: str = "fit") -> list[tuple[float, float, float]]:
    """One window every ``every`` seconds: (t0 at a stamp, logged q, estimated q̇)."""
    t = np.asarray(raw["t"], float) - raw["t"][0]
    q = np.asarray(raw["q"], float)
    out = []
    k = 0
    while k * every <= t[-1]:
        i = int(np.searchsorted(t, k * every - 1e-9, side="left"))
        if i >= len(t):
            break
        out.append((float(t[i]), float(q[i]), velocity_at(t, q, i, velocity, raw["qd"])))
        k += 1
    return out


def run_name(source: str) -> str:
    """``path/NAME.csv`` (or ``.csv.gz``, ``.mcap``, ``.json``) → ``NAME``."""
    name = Path(source).name
    for ext in (".csv.gz", ".csv", ".mcap", ".json"):
        if name.endswith(ext):
            return name[: -len(ext)]
    return name


def read_windows(path: Path) -> dict[str, list[tuple[float, float, float]]]:
    """The windows file simgap writes: runs by source name → [(t0, q0, q̇0)]."""
    with open(path) as f:
        data = json.load(f)
    out: dict[str, list] = {}
    for run in data["runs"]:
        ws = []
        for w in run["windows"]:
            q0, qd0 = w["q0"], w["qd0"]
            q0 = q0[0] if isinstance(q0, list) else q0
            qd0 = qd0[0] if isinstance(qd0, list) else qd0
            ws.append((float(w["t0"]), float(q0), float(qd0)))
        out.setdefault(run_name(run["source"]), []).extend(ws)
    return out


def _rms(x) -> float | None:
    x = np.asarray(x, float)
    return float(np.sqrt(np.mean(x * x))) if x.size else None


def evaluate(params: list, raws: list[dict], windows: dict[str, list], horizons=HORIZONS, holdout: list[str] | None = None, vin_mode: str = "nominal") -> dict:
    """All figures as a JSON-ready dict (radians). ``windows``: {run name: [(t0, q0, q̇0)]}."""
    horizons = [float(h) for h in horizons]
    holdout = [r["name"] for r in raws] if holdout is None else list(holdout)
    missing = [h for h in holdout if h not in {r["name"] for r in raws}]
    if missing:
        raise ValueError(f"held-out runs not among the logs evaluated: {missing}")
    runs = {}
    pooled_err = {p.label: {h: [] for h in horizons} for p in params}
    pooled_floor = {h: [] for h in horizons}
    for raw in raws:
        name = raw["name"]
        ws = windows.get(name, [])
        run = {"kp": raw["meta"]["kp"], "trajectory": raw["meta"].get("trajectory"), "n_windows": [], "floor_rms": [], "models": {}}
        floor_done = False
        for p in params:
            ks = kstep(p, raw, ws, horizons, vin_mode)
            if not floor_done:
                run["n_windows"] = [len(ks[h]["floor"]) for h in horizons]
                run["floor_rms"] = [_rms(ks[h]["floor"]) for h in horizons]
                if name in holdout:
                    for h in horizons:
                        pooled_floor[h].extend(ks[h]["floor"])
                floor_done = True
            if name in holdout:
                for h in horizons:
                    pooled_err[p.label][h].extend(ks[h]["model"])
            run["models"][p.label] = {
                "mae_bam": bam_mae(p, raw, vin_mode),
                "mae_raw": raw_mae(p, raw, vin_mode),
                "kstep_rms": [_rms(ks[h]["model"]) for h in horizons],
            }
        runs[name] = run
    pooled = {"runs": holdout, "n_windows": [len(pooled_floor[h]) for h in horizons], "floor_rms": [_rms(pooled_floor[h]) for h in horizons], "models": {}}
    for p in params:
        maes = [runs[n]["models"][p.label]["mae_bam"] for n in holdout]
        pooled["models"][p.label] = {
            "mae_bam_mean": float(np.mean(maes)),
            "mae_bam_std": float(np.std(maes)),
            "mae_raw_mean": float(np.mean([runs[n]["models"][p.label]["mae_raw"] for n in holdout])),
            "kstep_rms": [_rms(pooled_err[p.label][h]) for h in horizons],
        }
    published = [p.label for p in params if p.label.startswith("published/")]
    best = lambda labels: min(labels, key=lambda l: pooled["models"][l]["mae_bam_mean"]) if labels else None  # noqa: E731
    return {
        "units": "rad",
        "horizons_s": horizons,
        "vin": vin_mode,
        "measure": {
            "mae_bam": "BAM's bam/mae.py: whole-run mean |q_sim - q_log| of a rollout from the first sample with simulated control, on BAM's 5 ms resample (bam/process.py) of the raw log, all samples; pooled = mean over runs",
            "mae_raw": "the same rollout on the raw non-uniform stamps",
            "kstep_rms": "RMS over windows of q_sim(t0+h) - q_log(t0+h), restarted from (q0, qd0) at t0, logged goal and torque enable, raw timeline; pooled = RMS over all windows of the held-out runs",
            "floor_rms": "constant velocity q0 + qd0 h on the same windows",
        },
        "error_gain": {p.label: p.error_gain for p in params},
        "runs": runs,
        "pooled": pooled,
        "best_by_bam_mae": {"published": best(published), "all": best([p.label for p in params])},
    }


def markdown(res: dict) -> str:
    """Tables in mrad: BAM's MAE per run and model, then the k-step RMS per horizon with the floor."""
    labels = list(next(iter(res["runs"].values()))["models"].keys()) if res["runs"] else []
    hs = res["horizons_s"]
    pooled = res["pooled"]
    lines = [
        "# BAM's XL330 models on the Rhoban pendulum logs",
        "",
        f"All figures in mrad. Voltage: {res['vin']}. Held-out (pooled) runs: {', '.join(pooled['runs'])}.",
        f"Windows: {res.get('windows', 'as given')}. Error gain per file: " + ", ".join(f"{l} {g:.6g}" for l, g in res["error_gain"].items()) + ".",
        f"BAM's best model by its own measure (pooled mean MAE): published {res['best_by_bam_mae']['published']}, all files {res['best_by_bam_mae']['all']}.",
        "",
        "## Whole-run MAE (BAM's measure: 5 ms resample, simulated control, from the first sample)",
        "",
        "| run | kp | trajectory | " + " | ".join(labels) + " |",
        "|---|---|---|" + "---|" * len(labels),
    ]
    for name, run in res["runs"].items():
        lines.append(f"| {name} | {run['kp']} | {run['trajectory']} | " + " | ".join(f"{1000 * run['models'][l]['mae_bam']:.1f}" for l in labels) + " |")
    lines.append("| **pooled mean** | | | " + " | ".join(f"**{1000 * pooled['models'][l]['mae_bam_mean']:.1f}**" for l in labels) + " |")
    for k, h in enumerate(hs):
        lines += [
            "",
            f"## k-step RMS position error at {h:g} s (raw timeline, restarted from (q0, q̇0))",
            "",
            "| run | windows | floor | " + " | ".join(labels) + " |",
            "|---|---|---|" + "---|" * len(labels),
        ]
        fmt = lambda x: "–" if x is None else f"{1000 * x:.1f}"  # noqa: E731
        for name, run in res["runs"].items():
            lines.append(f"| {name} | {run['n_windows'][k]} | {fmt(run['floor_rms'][k])} | " + " | ".join(fmt(run["models"][l]["kstep_rms"][k]) for l in labels) + " |")
        lines.append(f"| **pooled** | {pooled['n_windows'][k]} | **{fmt(pooled['floor_rms'][k])}** | " + " | ".join(f"**{fmt(pooled['models'][l]['kstep_rms'][k])}**" for l in labels) + " |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="BAM's XL330 models as baselines: whole-run MAE, k-step RMS and the constant-velocity floor")
    ap.add_argument("--data", type=Path, default=default_data_dir(), help="the rhoban-bam-xl330 folder (default ../shared/data/rhoban-bam-xl330)")
    ap.add_argument("--logs", default=None, help="comma-separated run names (default: every raw log)")
    ap.add_argument("--params", type=Path, nargs="+", default=None, help="BAM params files (default: params/published/m*.json and params/xl330-branch/m*.json)")
    ap.add_argument("--error-gain", type=float, default=None, help="override the error gain of every params file")
    ap.add_argument("--holdout", default=None, help="comma-separated run names pooled in the summary (default: all evaluated)")
    ap.add_argument("--windows", type=Path, default=None, help='windows JSON {"runs": [{"source": "NAME.csv", "windows": [{"t0", "q0", "qd0"}]}]}')
    ap.add_argument("--every", type=float, default=0.1, help="spacing of the default windows [s]")
    ap.add_argument("--velocity", choices=["fit", "central", "speed"], default="fit", help="q̇0 of the default windows")
    ap.add_argument("--horizons", default=",".join(str(h) for h in HORIZONS))
    ap.add_argument("--vin", choices=["nominal", "logged"], default="nominal")
    ap.add_argument("--out-json", type=Path, default=None)
    ap.add_argument("--out-md", type=Path, default=None)
    args = ap.parse_args(argv)

    files = raw_logs(args.data)
    if args.logs:
        want = [s.strip() for s in args.logs.split(",") if s.strip()]
        by = {f.stem: f for f in files}
        unknown = [w for w in want if w not in by]
        if unknown:
            ap.error(f"no raw log named {unknown} in {args.data / 'raw'}")
        files = [by[w] for w in want]
    raws = [load_raw(f) for f in files]
    params = [load_params(f, args.error_gain) for f in (args.params or param_files(args.data))]
    if args.windows is not None:
        windows = read_windows(args.windows)
        absent = [n for n in windows if n not in {r["name"] for r in raws}]
        if absent:
            print(f"note: windows for runs not evaluated, ignored: {absent}", file=sys.stderr)
    else:
        windows = {r["name"]: default_windows(r, args.every, args.velocity) for r in raws}
    holdout = [s.strip() for s in args.holdout.split(",")] if args.holdout else None
    res = evaluate(params, raws, windows, [float(h) for h in args.horizons.split(",")], holdout, args.vin)
    res["windows"] = "file " + str(args.windows) if args.windows else f"every {args.every} s, q0 logged, qd0 {args.velocity}"
    md = markdown(res)
    if args.out_json:
        args.out_json.write_text(json.dumps(res, indent=1) + "\n")
    if args.out_md:
        args.out_md.write_text(md)
    if not args.out_md:
        print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
