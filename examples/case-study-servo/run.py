#!/usr/bin/env python3
"""The servo case study: simgap's diagnosis of the Rhoban BAM XL330 pendulum logs, held out by
trajectory, against BAM's published models on the same held-out logs and windows.

    python3 examples/case-study-servo/run.py --data ../shared/data/rhoban-bam-xl330 \\
        --bin target/release/simgap --out /tmp/servo-cs

Folds (chosen before any fit): leave one trajectory kind out. Each of the four trajectory kinds
(``sin_sin``, ``lift_and_drop``, ``up_and_down``, ``sin_time_square``) is held out in turn, with
all its gains; the diagnosis fits on the other kinds' logs only. For every fold:

1. ``simgap diagnose`` on the fit logs, the fold's logs held out (``OUT/fold-KIND/report.json``);
2. ``simgap predict`` of the held-out logs by the corrected model: the URDF, the report's
   ``servo`` constants (written into copies of the held-out sidecars) and its selected effects;
   it prints the k-step figures, the whole-run closed-loop mean absolute error and the window
   starts (``OUT/fold-KIND/predict.json``);
3. ``bam_baseline.py`` scores BAM's published M1–M6 on the same held-out logs, the same
   windows (start times and restart states from step 2) and BAM's own whole-run MAE.

The tables (markdown, on stdout and in ``OUT/tables.md``) put simgap's corrected model beside
BAM's published M1 and the best published BAM model *per figure and fold* (the most favourable
choice for BAM). Needs numpy for the BAM baselines (``bam_baseline.py``).
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import bam_to_simgap  # noqa: E402

TRAJECTORIES = ["sin_sin", "lift_and_drop", "up_and_down", "sin_time_square"]
PUBLISHED = [f"params/published/m{i}.json" for i in range(1, 7)]
HORIZONS = [0.1, 0.25, 0.5]


def effect_spec(e: dict, joints: list[str]) -> str:
    """A report's selected effect as simgap's command-line spelling (`name:p=v,...;...`), with
    per-joint parameters spread over the model's joints (neutral elsewhere)."""
    name, params = e["effect"], e["parameters"]
    if name == "inertial_error":
        parts = []
        for i, jname in enumerate(e["joints"]):
            j = joints.index(jname)
            com = params["delta_com"][i]
            inertia = params["delta_inertia"][i]
            parts.append(f"inertial_error:joint={j};mass={params['delta_mass'][i]!r};com={','.join(map(repr, com))};inertia={','.join(map(repr, inertia))}")
        return " ".join(parts)
    if not e["joints"]:
        body = ";".join(f"{k}={','.join(map(repr, v)) if isinstance(v, list) else repr(v)}" for k, v in params.items())
        return name + (":" + body if body else "")
    neutral = {"k": 1.0, "limit": float("inf"), "w": 0.01, "periods_per_rev": 1.0}
    if name == "joint_spring":
        neutral["k"] = 0.0
    fields = []
    for k, v in params.items():
        full = [neutral.get(k, 0.0)] * len(joints)
        for jname, x in zip(e["joints"], v):
            full[joints.index(jname)] = x
        fields.append(f"{k}={','.join('inf' if x == float('inf') else repr(x) for x in full)}")
    return f"{name}:{';'.join(fields)}"


def run(cmd: list[str]) -> str:
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"command failed ({p.returncode}): {' '.join(cmd)}\n{p.stdout}\n{p.stderr}")
    return p.stdout


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=bam_to_simgap.default_data_dir())
    ap.add_argument("--bin", type=Path, required=True, help="the simgap binary")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--voltage", choices=["nominal", "logged"], default="nominal", help="the converter's voltage choice (see bam_to_simgap.py)")
    ap.add_argument("--only", choices=TRAJECTORIES, default=None, help="one fold only")
    ap.add_argument("--load-stribeck-friction", action="store_true", help="diagnose with the load friction rising at rest tried (simgap diagnose --load-stribeck-friction)")
    args = ap.parse_args(argv)
    out = args.out
    logs_dir = out / "logs"
    bam_to_simgap.convert(args.data, logs_dir, logged_voltage=args.voltage == "logged")
    urdf = logs_dir / "pendulum.urdf"
    kinds = {p.stem: bam_to_simgap.load_raw(p)["meta"] for p in bam_to_simgap.raw_logs(args.data)}
    rows = []
    for kind in [args.only] if args.only else TRAJECTORIES:
        fold = out / f"fold-{kind}"
        fold.mkdir(parents=True, exist_ok=True)
        hold = [n for n, m in kinds.items() if m["trajectory"] == kind]
        fit = [n for n in kinds if n not in hold]
        cmd = [str(args.bin), "diagnose", "--urdf", str(urdf)]
        if args.load_stribeck_friction:
            cmd.append("--load-stribeck-friction")
        for n in fit:
            cmd += ["--log", str(logs_dir / f"{n}.csv")]
        for n in hold:
            cmd += ["--holdout", str(logs_dir / f"{n}.csv")]
        t0 = time.time()
        summary = run(cmd + ["--json", str(fold / "report.json")])
        seconds = time.time() - t0
        (fold / "summary.txt").write_text(summary)
        report = json.loads((fold / "report.json").read_text())
        # the corrected model: the report's servo constants in copies of the held-out sidecars
        pred_dir = fold / "heldout"
        pred_dir.mkdir(exist_ok=True)
        servo = report["servo"]
        for n in hold:
            shutil.copy(logs_dir / f"{n}.csv", pred_dir / f"{n}.csv")
            exp = json.loads((logs_dir / f"{n}.experiment.json").read_text())
            exp["kt"] = ",".join(map(repr, servo["kt"]))
            exp["R"] = ",".join(map(repr, servo["R"]))
            (pred_dir / f"{n}.experiment.json").write_text(json.dumps(exp, indent=2) + "\n")
        specs = " ".join(effect_spec(e, report["joints"]) for e in report["selected_effects"]).split()
        cmd = [str(args.bin), "predict", "--urdf", str(urdf), "--json", str(fold / "predict.json")]
        for n in hold:
            cmd += ["--log", str(pred_dir / f"{n}.csv")]
        for s in specs:
            cmd += ["--effect", s]
        run(cmd)
        pred = json.loads((fold / "predict.json").read_text())
        # the kstep of predict must be the report's (same windows, same model)
        for a, b in zip(pred["after"], report["gap"]["kstep"]["after"]):
            if abs(a - b) > 1e-9 * max(1.0, abs(b)):
                raise SystemExit(f"fold {kind}: predict gives {pred['after']} but the report {report['gap']['kstep']['after']}")
        windows = {"runs": [{"source": Path(r["log"]).name, "windows": r["window_starts"]} for r in pred["runs"]]}
        (fold / "windows.json").write_text(json.dumps(windows))
        bam_json = fold / "bam.json"
        run(
            [sys.executable, str(HERE / "bam_baseline.py"), "--data", str(args.data), "--logs", ",".join(hold), "--holdout", ",".join(hold)]
            + ["--windows", str(fold / "windows.json"), "--params", *[str(args.data / p) for p in PUBLISHED], "--out-json", str(bam_json), "--out-md", str(fold / "bam.md")]
        )
        bam = json.loads(bam_json.read_text())
        maes = [r["whole_run_mae"] for r in pred["runs"]]
        rows.append({"kind": kind, "hold": hold, "seconds": seconds, "report": report, "pred": pred, "bam": bam, "mae": (sum(m[0] for m in maes) / len(maes), sum(m[1] for m in maes) / len(maes))})
    text = tables(rows)
    (out / "tables.md").write_text(text)
    print(text)
    return 0


def bam_figures(bam: dict) -> dict[str, dict[str, float]]:
    """Per BAM parameter file: pooled k-step at each horizon and mean whole-run MAE [rad]."""
    out = {}
    for f, v in bam["pooled"]["models"].items():
        out[f] = {"mae": v["mae_bam_mean"], **{f"k{h}": v["kstep_rms"][i] for i, h in enumerate(HORIZONS)}}
    return out


def tables(rows: list[dict]) -> str:
    lines = ["| held-out trajectory (logs) | figure | URDF + servo law | simgap corrected | BAM M1 (published) | best published BAM | floor |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        bam = bam_figures(r["bam"])
        pred = r["pred"]
        label = f"{r['kind']} ({len(r['hold'])})"
        for i, h in enumerate(HORIZONS):
            m1 = bam["published/m1"][f"k{h}"]
            best = min(bam.items(), key=lambda kv: kv[1][f"k{h}"])
            lines.append(f"| {label} | k-step {h} s [mrad] | {1e3 * pred['before'][i]:.1f} | {1e3 * pred['after'][i]:.1f} | {1e3 * m1:.1f} | {1e3 * best[1][f'k{h}']:.1f} ({best[0].split('/')[-1]}) | {1e3 * pred['floor'][i]:.1f} |")
        m1 = bam["published/m1"]["mae"]
        best = min(bam.items(), key=lambda kv: kv[1]["mae"])
        lines.append(f"| {label} | whole-run MAE [mrad] | {1e3 * r['mae'][0]:.1f} | {1e3 * r['mae'][1]:.1f} | {1e3 * m1:.1f} | {1e3 * best[1]['mae']:.1f} ({best[0].split('/')[-1]}) | |")
    lines.append("")
    lines.append("Whole-run MAE per held-out log [mrad] (\"best published BAM\" is the fold's best model by its pooled MAE, as above):")
    lines.append("")
    lines.append("| held-out trajectory | log | firmware Kp | URDF + servo law | simgap corrected | BAM M1 (published) | best published BAM |")
    lines.append("|---|---|---|---|---|---|---|")
    for r in rows:
        bam = bam_figures(r["bam"])
        best = min(bam.items(), key=lambda kv: kv[1]["mae"])[0]
        for run_pred in r["pred"]["runs"]:
            name = Path(run_pred["log"]).stem
            b = r["bam"]["runs"][name]
            lines.append(
                f"| {r['kind']} | {name} | {b['kp']} | {1e3 * run_pred['whole_run_mae'][0]:.1f} | {1e3 * run_pred['whole_run_mae'][1]:.1f} | {1e3 * b['models']['published/m1']['mae_bam']:.1f} | {1e3 * b['models'][best]['mae_bam']:.1f} ({best.split('/')[-1]}) |"
            )
    lines.append("")
    lines.append("| held-out trajectory | selected effects | servo constants (kt [N·m/A], R [Ω], source; effective) | diagnosis time [s] |")
    lines.append("|---|---|---|---|")
    for r in rows:
        rep = r["report"]
        eff = "; ".join(f"{e['effect']} ({', '.join(f'{k} = ' + ', '.join(f'{x:.4g}' for x in (v if isinstance(v, list) and not any(isinstance(y, list) for y in v) else [float('nan')])) for k, v in e['parameters'].items())})" for e in rep["selected_effects"]) or "none"
        sv = rep["servo"]
        lines.append(f"| {r['kind']} | {eff} | {sv['kt'][0]:.4f}, {sv['R'][0]:.4f}, {sv['source']}; {sv['effective']['kt'][0]:.4f}, {sv['effective']['R'][0]:.4f} | {r['seconds']:.1f} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
