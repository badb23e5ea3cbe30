#!/usr/bin/env python3
"""The C.0 case study's corrected models, exported by `simgap diagnose --export-mjcf`, predicted
in MuJoCo on the held-out runs, beside simgap's own k-step figures (docs/results/case-study-dfki.md).

Run after `run.py --only c0` (which writes `c0_hold{i}.json`, `.xml`, `.urdf` and their
`.effects.json` sidecars into its --out), in a throwaway virtual environment:

    python3 -m venv /tmp/mjvenv2 && /tmp/mjvenv2/bin/pip install mujoco numpy
    python3 examples/case-study-dfki/run.py --data ../shared/data --bin BIN --out /tmp/cs --only c0
    /tmp/mjvenv2/bin/python examples/case-study-dfki/mujoco_kstep.py --data ../shared/data --cs /tmp/cs --bin BIN

For each fold the exported MJCF is loaded as written (`MjModel.from_xml_path`) and restarted at
every k-step window of the held-out run from the state simgap starts from, driven by the logged
torque `tau_con` held per sample (`ctrl`, zero-order hold). simgap's report does not list its
windows, so this script lays them as `crates/simgap-diag/src/prediction/kstep.rs` does, from
the same inputs: the CSV columns simgap reads (`pos_meas`, `tau_con`), its glitch repair
(`prepare/robust.rs`), its smoothing differentiator (local cubic fits over 0.05 s,
`prepare/differentiate.rs`) for the start state q̂, q̂̇ and the valid range, windows every 0.1 s
on that range, ends at the first sample at or after t0 + h − T/2, the error against the logged
position capped at π per joint, and the figure sqrt(mean over windows of ‖e‖²). The
constant-velocity floor computed on these windows is printed beside the report's: equal
figures mean equal windows and start states.

MuJoCo is stepped two ways:
  * `as written`: one `mj_step` of the file's timestep (the experiment's 0.002 s) per logged
    sample, the error taken at the same sample as simgap's. The C.0 stamps are 0.0020001 s
    apart, with a few gaps of up to 8 ms, so MuJoCo covers slightly less time than the log;
  * `log stamps`: each logged interval Δt integrated in ceil(Δt / timestep) equal steps
    (`m.opt.timestep` set at run time, the file untouched), the rule simgap's simulator uses
    for an interval that is not exactly the period (`crates/simgap-sim/src/step.rs`).

With --bin it also runs two checks with `simgap predict` on the same windows: the exported URDF
plus the effects its sidecar lists (what the file cannot hold, and the friction it holds but
simgap does not read from URDF) must give the report's corrected-model figure; and without dry
friction on both sides (MuJoCo's `dof_frictionloss` zeroed at run time, no Coulomb term in
simgap) MuJoCo with log-stamp steps and simgap must predict alike. Outputs go to --cs.
"""
import argparse
import bisect
import csv
import gzip
import json
import math
import os
import subprocess

import mujoco
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
WINDOW_S = 0.05  # PrepareOptions::default().window
MAX_WINDOWS = 200  # kstep::MAX_WINDOWS_PER_RUN
CAP = math.pi


def read_c0(path):
    """Time, q = pos_meas1/2 and τ = tau_con1/2, as simgap's DFKI CSV mapping reads them."""
    with gzip.open(path, "rt") as f:
        rows = csv.reader(f)
        col = {name: i for i, name in enumerate(next(rows))}
        data = [[float(r[col[c]]) for c in ("time", "pos_meas1", "pos_meas2", "tau_con1", "tau_con2")] for r in rows]
    a = np.array(data)
    return a[:, 0], a[:, 1:3].copy(), a[:, 3:5].copy()


def repair_glitches(t, q):
    """simgap's glitch repair: a sample far from the mean of its neighbours (beyond 50 robust σ
    of that difference, a floor from the acceleration, 1 mrad and 5 encoder steps, and beyond
    the neighbours' own difference) is replaced by that mean. Returns the repaired samples."""
    found = []
    for j in range(q.shape[1]):
        x = q[:, j].copy()
        d = np.zeros(len(x))
        d[1:-1] = x[1:-1] - 0.5 * (x[:-2] + x[2:])
        sigma = 1.4826 * np.sort(np.abs(d))[len(d) // 2]
        inc = np.abs(np.diff(x))
        step = inc[inc > 0].min() if np.any(inc > 0) else 0.0
        for k in range(1, len(x) - 1):
            dt = t[k + 1] - t[k - 1]
            floor = max(1000.0 * dt * dt / 4.0, 1e-3, 5.0 * step)
            if abs(d[k]) > max(50.0 * sigma, floor) and abs(d[k]) > abs(x[k + 1] - x[k - 1]):
                q[k, j] = 0.5 * (x[k - 1] + x[k + 1])
                found.append((k, j))
    return found


def smooth(t, q, window=WINDOW_S):
    """q̂, q̂̇ on the valid range of simgap's smoothing differentiator (value and first
    derivative of a cubic least-squares fit over ±half samples, time scaled by half the span)."""
    n = len(t)
    dt = (t[-1] - t[0]) / (n - 1)
    half = min(max(int(math.floor(window / dt / 2.0 + 0.5)), 3), 200)
    valid = range(half, n - half)
    q_hat, qd_hat = np.zeros_like(q), np.zeros_like(q)
    for k in valid:
        scale = (t[k + half] - t[k - half]) / 2.0
        s = (t[k - half:k + half + 1] - t[k]) / scale
        a = np.vander(s, 4, increasing=True)
        w = np.linalg.inv(a.T @ a) @ a.T  # row d: weights of coefficient d
        seg = q[k - half:k + half + 1]
        q_hat[k] = w[0] @ seg
        qd_hat[k] = (w[1] / scale) @ seg
    return q_hat, qd_hat, valid


def windows(t, valid, horizons, period, max_windows=MAX_WINDOWS):
    """Window starts and, per horizon, end samples (None past the valid range), as kstep.rs."""
    stride = max(min(horizons), period)
    span = t[valid[-1]] - t[valid[0]]
    stride = max(stride, span / max_windows)
    out, next_t = [], t[valid[0]]
    for k in valid:
        if t[k] + 1e-12 < next_t:
            continue
        next_t = t[k] + stride
        ends = []
        for h in horizons:
            j = bisect.bisect_left(t, t[k] + h - 0.5 * period)
            ends.append(j if j < valid.stop and h > 0 else None)
        if all(e is None for e in ends):
            break
        out.append((k, ends))
    return out


def capped(e):
    e = np.where(np.isfinite(e), np.abs(e), CAP)
    return np.minimum(e, CAP)


def rms(errors, nh):
    """Per horizon, sqrt(mean over windows of ‖e‖²) of `errors[w][h]` (None: no such end)."""
    out = []
    for h in range(nh):
        rows = [e[h] for e in errors if e[h] is not None]
        out.append(float(np.sqrt(np.mean([np.sum(r * r) for r in rows]))) if rows else float("nan"))
    return out


def floor_errors(t, q, q_hat, qd_hat, wins):
    return [[None if k1 is None else capped(q_hat[k0] + qd_hat[k0] * (t[k1] - t[k0]) - q[k1]) for k1 in ends] for k0, ends in wins]


def mujoco_errors(m, t, q, tau, q_hat, qd_hat, wins, log_stamps):
    """MuJoCo restarted at every window from (q̂, q̂̇), `ctrl` = the logged torque of each sample."""
    d = mujoco.MjData(m)
    base = m.opt.timestep
    out = []
    for k0, ends in wins:
        mujoco.mj_resetData(m, d)
        d.qpos[:] = q_hat[k0]
        d.qvel[:] = qd_hat[k0]
        last = max(e for e in ends if e is not None)
        at = {}
        for k in range(k0, last):
            d.ctrl[:] = tau[k]
            if log_stamps:
                dt = t[k + 1] - t[k]
                steps = max(1, math.ceil(dt / base * (1.0 - 1e-9)))
                m.opt.timestep = dt / steps
            else:
                steps = 1
            for _ in range(steps):
                mujoco.mj_step(m, d)
            at[k + 1] = d.qpos.copy()
        m.opt.timestep = base
        out.append([None if k1 is None else capped(at[k1] - q[k1]) for k1 in ends])
    return out


def cli_effects(entries, joints, drop=(), width=None):
    """Report-form effects (a sidecar's) in `simgap predict --effect` spelling, per joint in
    model order (0 where an effect does not act; a dry friction's width 0.01 there), without
    the effects named in `drop`; `width`: every dry-friction width w replaced by this one."""
    specs = []
    for e in entries:
        if e["effect"] in drop:
            continue
        parts = []
        for key, vals in e["parameters"].items():
            full = [0.01 if key == "w" else 0.0] * len(joints)
            for name, v in zip(e["joints"], vals):
                full[joints.index(name)] = width if key == "w" and width is not None else v
            parts.append(f"{key}={','.join(repr(float(v)) for v in full)}")
        specs.append(f"{e['effect']}:{';'.join(parts)}")
    return specs


def simgap_predict(args, urdf, log, effects, exp, horizons, tag):
    js = os.path.join(args.cs, f"{tag}.json")
    cmd = [args.bin, "predict", "--urdf", urdf, "--log", log, "--experiment", exp, "--horizon", ",".join(map(str, horizons)), "--json", js]
    for e in effects:
        cmd += ["--effect", e]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with open(js) as f:
        return json.load(f)


def fmt(v):
    return f"{v:.4f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default="../shared/data")
    ap.add_argument("--cs", default="/tmp/cs", help="run.py's --out (reports and exported models)")
    ap.add_argument("--bin", help="simgap binary for the `simgap predict` checks (left out: no checks)")
    ap.add_argument("--folds", default="0,1,2,3,4")
    args = ap.parse_args()
    C = os.path.join(args.data, "dfki-double-pendulum/experiment_records/design_C.0/20220914/sys_id")
    exp_path = os.path.join(HERE, "dfki-c0.experiment.json")
    with open(exp_path) as f:
        period = float(json.load(f)["sample_period"])
    print(f"# MuJoCo {mujoco.__version__}: the exported corrected MJCF of each C.0 fold on its held-out run")
    rows, checks, summary = [], [], []
    for i in [int(x) for x in args.folds.split(",")]:
        tag = f"c0_hold{i}"
        with open(os.path.join(args.cs, f"{tag}.json")) as f:
            rep = json.load(f)
        ks = rep["gap"]["kstep"]
        horizons = ks["horizons_s"]
        run = ks["runs"][0]
        log = os.path.join(C, f"trajectory_0{i}.csv.gz")
        t, q, tau = read_c0(log)
        glitches = repair_glitches(t, q)
        q_hat, qd_hat, valid = smooth(t, q)
        wins = windows(t, valid, horizons, period)
        fl = rms(floor_errors(t, q, q_hat, qd_hat, wins), len(horizons))
        xml = os.path.join(args.cs, f"{tag}.xml")
        m = mujoco.MjModel.from_xml_path(xml)
        joints = [m.joint(j).name for j in range(m.njnt)]
        mj = {mode: rms(mujoco_errors(m, t, q, tau, q_hat, qd_hat, wins, mode), len(horizons)) for mode in (False, True)}
        # the same file with the friction-loss row the export wrote before (a time constant of
        # 2 timesteps, MuJoCo's default impedance 0.9), set at run time: both numbers of the
        # solref, since a positive time constant beside the file's direct-format damping is a
        # "mixed solref format" MuJoCo replaces by its default (with a warning every step)
        stiff = mujoco.MjModel.from_xml_path(xml)
        stiff.dof_solref[:] = [2.0 * stiff.opt.timestep, 1.0]
        stiff.dof_solimp[:] = [0.9, 0.95, 0.001, 0.5, 2.0]
        mj_stiff = rms(mujoco_errors(stiff, t, q, tau, q_hat, qd_hat, wins, True), len(horizons))
        with open(xml + ".effects.json") as f:
            left_out = [e["effect"] for e in json.load(f)["selected_effects"]]
        r = {"held": f"trajectory_0{i}", "horizons": horizons, "windows": len(wins), "report_windows": run["windows"],
             "glitches": len(glitches), "gaps": int(np.sum(np.diff(t) > 1.5 * period)), "longest_interval": float(np.diff(t).max()),
             "median_interval": float(np.median(np.diff(t))), "floor_py": fl, "floor": run["floor"], "before": run["before"], "after": run["after"],
             "mujoco_as_written": mj[False], "mujoco_log_stamps": mj[True], "mujoco_log_stamps_stiff_friction": mj_stiff,
             "friction_solref_default": [float(x) for x in m.dof_solref[0]], "mjcf_sidecar": left_out}
        if args.bin:
            urdf = os.path.join(args.cs, f"{tag}.urdf")
            with open(urdf + ".effects.json") as f:
                side = json.load(f)
            # the URDF holds the inertials; simgap reads no <dynamics>, so the friction it holds
            # is given as effects too
            entries = side["selected_effects"] + [e for e in side["held"] if e["effect"] != "inertial_error"]
            eff = cli_effects(entries, joints)
            r["urdf_effects"] = eff
            r["simgap_exported_urdf"] = simgap_predict(args, urdf, log, eff, exp_path, horizons, f"{tag}_urdf_predict")["after"]
            # the tanh width, 10 times narrower (closer to an exact sign)
            narrow = cli_effects(entries, joints, width=0.001)
            r["simgap_w_0.001"] = simgap_predict(args, urdf, log, narrow, exp_path, horizons, f"{tag}_w0.001_predict")["after"]
            nodry = cli_effects(entries, joints, drop=("coulomb_friction",))
            r["simgap_no_dry"] = simgap_predict(args, urdf, log, nodry, exp_path, horizons, f"{tag}_nodry_predict")["after"]
            m0 = mujoco.MjModel.from_xml_path(xml)
            m0.dof_frictionloss[:] = 0.0
            r["mujoco_no_dry"] = rms(mujoco_errors(m0, t, q, tau, q_hat, qd_hat, wins, True), len(horizons))
        summary.append(r)
    with open(os.path.join(args.cs, "mujoco_kstep.json"), "w") as f:
        json.dump(summary, f, indent=1)

    ix = [summary[0]["horizons"].index(h) for h in (0.1, 0.5)]
    cols = ("published URDF", "simgap corrected", "MuJoCo, exported MJCF", "MuJoCo, log stamps", "floor")
    print("\n| held-out run | " + " | ".join(f"{c} {h} s" for h in (0.1, 0.5) for c in cols) + " |")
    print("|---|" + "---:|" * (2 * len(cols)))
    for r in summary:
        cells = []
        for h in ix:
            cells += [r["before"][h], r["after"][h], r["mujoco_as_written"][h], r["mujoco_log_stamps"][h], r["floor"][h]]
        print(f"| {r['held']} | " + " | ".join(fmt(c) for c in cells) + " |")
    print("\nk-step RMS position error [rad] (sqrt of the mean over windows of the squared error norm over both joints).")
    print("\nWindows (script against the report) and checks, all horizons " + ", ".join(f"{h} s" for h in summary[0]["horizons"]) + ":")
    for r in summary:
        rel = max(abs(a - b) / b for a, b in zip(r["floor_py"], r["floor"]))
        line = (f"- {r['held']}: {r['windows']} windows ({r['report_windows']} in the report), {r['glitches']} glitch samples repaired, "
                f"median interval {r['median_interval'] * 1e3:.7f} ms, {r['gaps']} intervals over 1.5 periods (longest {r['longest_interval'] * 1e3:.1f} ms); "
                f"floor {', '.join(f'{x:.6f}' for x in r['floor_py'])} (report {', '.join(f'{x:.6f}' for x in r['floor'])}, largest rel. difference {rel:.1e}); "
                f"MJCF sidecar: {', '.join(r['mjcf_sidecar']) or 'nothing left out'}; "
                f"MuJoCo (log stamps) with the file's friction row (solref {r['friction_solref_default']}): "
                f"{', '.join(f'{x:.4f}' for x in r['mujoco_log_stamps'])}, with a two-step row: "
                f"{', '.join(f'{x:.4f}' for x in r['mujoco_log_stamps_stiff_friction'])}")
        if "simgap_exported_urdf" in r:
            rel_u = max(abs(a - b) / b for a, b in zip(r["simgap_exported_urdf"], r["after"]))
            rel_n = max(abs(a - b) / b for a, b in zip(r["mujoco_no_dry"], r["simgap_no_dry"]))
            line += (f"; simgap on the exported URDF + sidecar {', '.join(f'{x:.6f}' for x in r['simgap_exported_urdf'])} "
                     f"(report's corrected {', '.join(f'{x:.6f}' for x in r['after'])}, rel. {rel_u:.1e}); "
                     f"without dry friction: simgap {', '.join(f'{x:.6f}' for x in r['simgap_no_dry'])}, "
                     f"MuJoCo (log stamps) {', '.join(f'{x:.6f}' for x in r['mujoco_no_dry'])} (rel. {rel_n:.1e}); "
                     f"simgap with the Coulomb width w = 0.001 rad/s: {', '.join(f'{x:.4f}' for x in r['simgap_w_0.001'])}")
        print(line)


if __name__ == "__main__":
    main()
