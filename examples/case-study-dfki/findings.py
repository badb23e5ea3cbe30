#!/usr/bin/env python3
"""Are the diagnosis's findings true? Each effect the establishment rule kept or dropped on the
DFKI records, checked afterwards on the held-out run it never saw (docs/results/findings.md).

Run after run.py, from the repository root, on the same --out (and, for the XL330 servo, after
examples/case-study-servo/run.py, on its --out given as --servo; for the SO-101, on the JSON
report of the diagnosis docs/results/case-study-so101.md runs, given as --so101):

    python3 examples/case-study-dfki/run.py --data ../shared/data --bin target/release/simgap --out /tmp/cs
    python3 examples/case-study-servo/run.py --data ../shared/data/rhoban-bam-xl330 --bin target/release/simgap --out /tmp/servo-cs
    target/release/simgap diagnose --urdf ../shared/data/sage-so101/so101_new_calib.urdf \
        --log '../shared/data/sage-so101/lerobot#4,17,21' --holdout '../shared/data/sage-so101/lerobot#14,18,24,31,37' \
        --experiment examples/case-study-so101/so101.experiment.json --json /tmp/so101.json
    python3 examples/case-study-dfki/findings.py --data ../shared/data --bin target/release/simgap --out /tmp/cs \
        --servo /tmp/servo-cs --so101 /tmp/so101.json

Python 3 standard library only. For every diagnosis report run.py wrote (`c0_hold0..4.json`,
`a0.json`, `sp_hold_*.json`; the servo's `fold-*/report.json`, whose held-out logs are predicted
from the copies that run.py gives the report's servo constants, `fold-*/heldout/`):

  * every **kept** term (a selected effect on one joint; an inertial correction as a whole) is
    taken out of the corrected model, and `simgap predict` scores the rest on the held-out run:
    the held-out run agrees with keeping it when the model is worse without it;
  * every **dropped** term (the report's `dropped_effects`) comes with the held-out k-step error of
    the corrected model with it added (`holdout_kstep_with`, measured by the diagnosis after its
    decisions): the held-out run agrees with dropping it when that is not better.

"Worse" and "better" compare the geometric mean over the 0.1 s and 0.5 s horizons, the figure
selection uses on the fit runs; a change within 1 % either way is "no difference". The held-out
runs decide nothing in the diagnosis: this script reads them only after the reports are written.
Prints one markdown table.
"""
import argparse
import json
import math
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
HORIZONS = (0.1, 0.5)
# within this relative change a term makes no difference on the held-out run
SAME = 0.01


def servo_cases(out):
    """(report, URDF, held-out logs, label) of every fold the servo case study's run.py writes."""
    if not out:
        return []
    folds = sorted(d for d in os.listdir(out) if d.startswith("fold-") and os.path.exists(os.path.join(out, d, "report.json")))
    urdf = os.path.join(out, "logs", "pendulum.urdf")
    return [
        (os.path.join(out, d, "report.json"), urdf, sorted(os.path.join(out, d, "heldout", f) for f in os.listdir(os.path.join(out, d, "heldout")) if f.endswith(".csv")),
         f"XL330 servo, {d[len('fold-'):]} held out")
        for d in folds
    ]


def so101_case(report, data, tmp_dir):
    """(report, URDF, held-out logs, experiment, label) of an SO-101 diagnosis report: the
    published URDF (its gripper locked by simgap), the report's held-out episodes, the case
    study's experiment file with the report's servo constants where the diagnosis fitted them."""
    if not report:
        return []
    try:
        with open(report) as f:
            rep = json.load(f)
        held_logs = rep["holdout_logs"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise SystemExit(f"--so101 {report}: expected the JSON report of `simgap diagnose --json` with held-out episodes ({e})")
    experiment = os.path.join(HERE, "..", "case-study-so101", "so101.experiment.json")
    servo = rep.get("servo") or {}
    if servo.get("source") == "fitted":
        with open(experiment) as f:
            e = json.load(f)
        e["kt"] = ",".join(map(repr, servo["kt"]))
        e["R"] = ",".join(map(repr, servo["R"]))
        experiment = os.path.join(tmp_dir, "so101_fitted.experiment.json")
        with open(experiment, "w") as f:
            json.dump(e, f)
    held = [h.split("#")[-1] for h in held_logs]
    label = f"SO-101, episodes {', '.join(held)} held out"
    return [(report, os.path.join(data, "sage-so101/so101_new_calib.urdf"), held_logs, experiment, label)]


def cases(data, out):
    """(report, URDF, experiment or None, label) of every diagnosis run.py writes."""
    dp = os.path.join(data, "dfki-double-pendulum/system_identification/identified_parameters")
    c0 = (os.path.join(dp, "design_C.0/model_3.1/acrobot.urdf"), os.path.join(HERE, "dfki-c0.experiment.json"))
    a0 = (os.path.join(dp, "design_A.0/model_2.1/pendubot.urdf"), os.path.join(HERE, "dfki-a0.experiment.json"))
    sp = (os.path.join(data, "dfki-simple-pendulum/urdf/simplependul_dfki_pino_Modi.urdf"), None)
    out_cases = [(f"c0_hold{i}.json", *c0, f"C.0, run 0{i} held out") for i in range(5)]
    out_cases.append(("a0.json", *a0, "A.0, second half held out"))
    out_cases.append(("sp_hold_gravcomp.json", *sp, "simple pendulum, gravity compensation held out"))
    out_cases.append(("sp_hold_pd.json", *sp, "simple pendulum, PD record held out"))
    return [(os.path.join(out, r), u, e, l) for r, u, e, l in out_cases if os.path.exists(os.path.join(out, r))]


def terms(entry):
    """The terms of a report entry: (effect, joint or None)."""
    if entry["effect"] == "inertial_error" or not entry.get("joints"):
        return [(entry["effect"], None)]
    return [(entry["effect"], j) for j in entry["joints"]]


# the value of no effect of a parameter, where it is not 0
NEUTRAL = {("torque_gain", "k"): 1.0, ("torque_saturation", "limit"): float("inf"), ("cogging", "periods_per_rev"): 1.0}


def specs(entries, joints, without=None):
    """`simgap predict --effect` spellings of report entries (per-joint parameters as one value a
    model joint, 0 where the entry does not act), leaving out the term `without`."""
    out = []
    for e in entries:
        name, p = e["effect"], e.get("parameters") or {}
        if name == "inertial_error":
            if without == (name, None):
                continue
            for k, jn in enumerate(e["joints"]):
                com = ",".join(repr(x) for x in p["delta_com"][k])
                inertia = ",".join(repr(x) for x in p["delta_inertia"][k])
                out.append(f"inertial_error:joint={joints.index(jn)};mass={p['delta_mass'][k]!r};com={com};inertia={inertia}")
            continue
        if not e.get("joints"):
            if without == (name, None):
                continue
            parts = [f"{k}={','.join(repr(x) for x in v) if isinstance(v, list) else repr(v)}" for k, v in p.items()]
            out.append(name + (":" + ";".join(parts) if parts else ""))
            continue
        acting = [j for j in e["joints"] if without != (name, j)]
        if not acting:
            continue
        parts = []
        for k, v in p.items():
            full = [NEUTRAL.get((name, k), 0.0)] * len(joints)
            for jn, x in zip(e["joints"], v):
                if jn in acting:
                    full[joints.index(jn)] = x
            if k == "w":
                full = [x if x > 0 else 0.01 for x in full]
            parts.append(f"{k}={','.join(repr(x) for x in full)}")
        out.append(f"{name}:{';'.join(parts)}")
    return out


def predict(binary, urdf, logs, experiment, effects, tmp):
    """Held-out k-step RMS at HORIZONS of the URDF plus `effects`, over the windows of `logs`."""
    cmd = [binary, "predict", "--urdf", urdf, "--horizon", ",".join(str(h) for h in HORIZONS), "--json", tmp]
    for log in logs:
        cmd += ["--log", log]
    if experiment:
        cmd += ["--experiment", experiment]
    for e in effects:
        cmd += ["--effect", e]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}:\n{r.stderr[-2000:]}")
    with open(tmp) as f:
        return json.load(f)["after"]


def at(kstep, values, h):
    i = min(range(len(kstep["horizons_s"])), key=lambda k: abs(kstep["horizons_s"][k] - h))
    return values[i]


def score(v):
    return math.exp(sum(math.log(x) for x in v) / len(v)) if all(x and x > 0 for x in v) else float("nan")


def verdict(kept, ratio):
    """Whether the held-out run agrees: `ratio` is (model without the term) / (model with it)."""
    if not math.isfinite(ratio):
        return "n/a"
    if abs(ratio - 1.0) <= SAME:
        return "no difference"
    return "yes" if (ratio > 1.0) == kept else "**no**"


def fmt(x):
    return "n/a" if x is None or not math.isfinite(x) else f"{x:.4f}"


def interval(entry, joint):
    """`name = value [lo, hi]` of every parameter of the entry on `joint` (the 95 % intervals)."""
    p, u = entry.get("parameters") or {}, entry.get("uncertainty") or {}
    at_joint = (lambda v: v[entry["joints"].index(joint)]) if joint else (lambda v: v)
    out = []
    for k, v in p.items():
        if k in ("w", "identifiable_directions") or entry["effect"] == "inertial_error":
            continue
        x = at_joint(v) if isinstance(v, list) else v
        h = u.get(k)
        h = at_joint(h) if isinstance(h, list) else h
        if isinstance(x, (int, float)):
            out.append(f"{k} = {x:.4g}" + (f" [{x - h:.3g}, {x + h:.3g}]" if isinstance(h, (int, float)) and math.isfinite(h) else ""))
    return "; ".join(out) or "(inertial correction)"


def evidence(rep, effect, joint, kept):
    """The fit runs' evidence behind the decision, from the report's own words."""
    if not kept:
        d = next(d for d in rep["dropped_effects"] if d["effect"] == effect and (joint is None or joint in d["joints"]))
        s = d["rule"]
        if d.get("fit_score_with") is not None:
            s += f"; fit runs {d['fit_score_with']:.3f} with, {d['fit_score_without']:.3f} without"
        return s
    e = next(e for e in rep["selected_effects"] if e["effect"] == effect and (joint is None or joint in e["joints"]))
    description = e.get("description", "")
    on = f" on {joint}" if joint else ""
    if f"established by prediction{on}" in description or f"not established{on}" in description:
        return "kept by prediction, its interval holding no effect"
    if effect == "inertial_error":
        return "physically consistent (judged by its own solver, not an interval)"
    finite = [x for v in (e.get("uncertainty") or {}).values() for x in (v if isinstance(v, list) else [v]) if isinstance(x, (int, float)) and math.isfinite(x)]
    return "its interval excludes the value of no effect" if finite else "searched on a grid (no interval)"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default="../shared/data")
    ap.add_argument("--bin", default="target/release/simgap")
    ap.add_argument("--out", default="/tmp/cs")
    ap.add_argument("--servo", default=None, help="the --out of examples/case-study-servo/run.py (optional)")
    ap.add_argument("--so101", default=None, help="the JSON report of an SO-101 diagnosis (optional; see above)")
    args = ap.parse_args()
    tmp = os.path.join(args.out, "findings_predict.json")
    rows = []
    every = [(p, u, [], e, l) for p, u, e, l in cases(args.data, args.out)] + [(p, u, logs, None, l) for p, u, logs, l in servo_cases(args.servo)]
    every += so101_case(args.so101, args.data, args.out)
    for path, urdf, logs, experiment, label in every:
        with open(path) as f:
            rep = json.load(f)
        joints, k = rep["joints"], rep["gap"]["kstep"]
        logs = logs or rep["holdout_logs"]
        selected = rep["selected_effects"]
        with_all = [at(k, k["after"], h) for h in HORIZONS]
        # the corrected model as `simgap predict` spells it must predict what the report says
        again = predict(args.bin, urdf, logs, experiment, specs(selected, joints), tmp)
        if any(abs(a - b) > 1e-3 * b for a, b in zip(again, with_all)):
            raise SystemExit(f"{path}: the selected effects predict {again} here, the report says {with_all}")
        for e in selected:
            for t in terms(e):
                without = predict(args.bin, urdf, logs, experiment, specs(selected, joints, without=t), tmp)
                ratio = score(without) / score(with_all)
                rows.append((label, t, "kept", interval(e, t[1]), evidence(rep, *t, True), with_all, without, verdict(True, ratio)))
        for d in rep.get("dropped_effects", []):
            for t in terms(d):
                with_it = [at(k, d["holdout_kstep_with"], h) for h in HORIZONS]
                ratio = score(with_all) / score(with_it)
                rows.append((label, t, "dropped", interval(d, t[1]), evidence(rep, *t, False), with_it, with_all, verdict(False, ratio)))
        print(f"{label}: {len(selected)} selected, {len(rep.get('dropped_effects', []))} dropped", file=sys.stderr)
    print("| case | effect | decision | values [95 % interval] | fit-run evidence | held-out with it 0.1 / 0.5 s [rad] | without it 0.1 / 0.5 s [rad] | held-out agrees |")
    print("|---|---|---|---|---|---|---|---|")
    for label, (effect, joint), decision, values, why, w, wo, agree in rows:
        name = f"`{effect}`" + (f" on {joint}" if joint else "")
        print(f"| {label} | {name} | {decision} | {values} | {why} | {fmt(w[0])} / {fmt(w[1])} | {fmt(wo[0])} / {fmt(wo[1])} | {agree} |")
    agree = [r[-1] for r in rows]
    print(f"\n{sum(a == 'yes' for a in agree)} of {len(rows)} decisions agree with the held-out run, "
          f"{sum(a == '**no**' for a in agree)} disagree, {sum(a == 'no difference' for a in agree)} make no difference (within {100 * SAME:.0f} %).")


if __name__ == "__main__":
    main()
