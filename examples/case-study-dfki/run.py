#!/usr/bin/env python3
"""Reproduce the DFKI case study (docs/results/case-study-dfki.md): diagnoses, held-out k-step figures and the
comparison with DFKI's own identified models, printed as markdown tables.

Run from the repository root:

    python3 examples/case-study-dfki/run.py --data ../shared/data --bin target/release/simgap --out /tmp/cs

Python 3 standard library only. Everything the script writes (split logs, sidecars, corrected
URDFs, JSON reports) goes to --out; nothing is written into the repository. Each C.0 diagnosis
also exports its corrected model (`c0_hold{i}.urdf`, `c0_hold{i}.xml`, each with its
`.effects.json` sidecar), which `mujoco_kstep.py` then predicts in MuJoCo. The data files are
read where they are (they are not part of this repository).

Data sets:
  * DFKI double pendulum, design C.0, open-loop sys_id trajectory_00..04: leave one run out (fit on
    four runs, hold out the fifth), five diagnoses.
  * DFKI double pendulum, design A.0, PD tracking record: first half fitted, second half held out
    (split by examples/case-study-dfki/split_a0.py, which adds the interpolated reference).
  * DFKI simple pendulum: the PD system-identification record and the gravity-compensation
    record, both replayed with the torque the motor reports; each is held out once while the
    other is fitted (two diagnoses).
For every held-out run, `simgap predict` also scores DFKI's identified model, built from the
published parameters as a corrected URDF plus effects (see `dfki_model_*` below).
"""
import argparse
import csv
import gzip
import json
import math
import os
import shutil
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

HERE = os.path.dirname(os.path.abspath(__file__))
HORIZONS = "0.1,0.5"


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def read_yaml_scalars(path):
    """model_parameters.yml files are flat `key: number` lines."""
    out = {}
    with open(path) as f:
        for line in f:
            line = line.split("#")[0].strip()
            if ":" in line:
                k, v = line.split(":", 1)
                try:
                    out[k.strip()] = float(v)
                except ValueError:
                    pass
    return out


def read_sysid_txt(path):
    """The simple pendulum's system_identification.txt: `name = value` lines."""
    out = {}
    with open(path) as f:
        for line in f:
            if "=" in line and not line.startswith("tau"):
                k, v = line.split("=", 1)
                out[k.strip()] = float(v)
    return out


def set_inertial(link, mass, com_z, i_com):
    """Sets a link's mass, COM (along z, as the published file places it) and an isotropic inertia
    about the COM (only the component about the joint axis matters for these planar robots)."""
    inertial = link.find("inertial")
    inertial.find("origin").set("xyz", f"0 0 {com_z!r}")
    inertial.find("mass").set("value", repr(mass))
    it = inertial.find("inertia")
    for k in ("ixx", "iyy", "izz"):
        it.set(k, repr(i_com))
    for k in ("ixy", "ixz", "iyz"):
        it.set(k, "0.0")


def dfki_model_double(urdf_in, params, urdf_out):
    """DFKI's identified double-pendulum model as URDF + effects.

    DFKI's I1, I2 are inertias about the joint axes; the published URDFs put that number as the
    COM inertia. Corrected: I_com = I - m r^2 (an error when negative: not physical). Rotor
    inertia: M11 += (gr^2 + 1) Ir, M22 += gr^2 Ir as joint armature; the off-diagonal -gr Ir of
    M12 has no URDF/armature equivalent and is left out. Friction b q' + cf atan(100 q'):
    viscous b and Coulomb fc = cf pi/2 (simgap's Coulomb is fc tanh(q'/0.01), close in shape).
    Returns (effects, description) or raises ValueError when the model is not physical."""
    p = params
    icom = [p["I1"] - p["m1"] * p["r1"] ** 2, p["I2"] - p["m2"] * p["r2"] ** 2]
    for j, v in enumerate(icom):
        if v < 0:
            raise ValueError(
                f"I{j+1} - m{j+1} r{j+1}^2 = {p[f'I{j+1}']:.5f} - {p[f'm{j+1}']:.4f}*{p[f'r{j+1}']:.4f}^2 = {v:.5f} kg m^2 < 0: "
                "a negative inertia about the centre of mass (not physical)")
    tree = ET.parse(urdf_in)
    root = tree.getroot()
    links = {l.get("name"): l for l in root.findall("link")}
    for j, name in enumerate(["Link1", "Link2"]):
        z_pub = float(links[name].find("inertial/origin").get("xyz").split()[2])
        r = p[f"r{j+1}"]
        set_inertial(links[name], p[f"m{j+1}"], math.copysign(r, z_pub), icom[j])
    tree.write(urdf_out)
    gr, ir = p["gr"], p["Ir"]
    arm = [(gr * gr + 1) * ir, gr * gr * ir]
    fc = [p["cf1"] * math.pi / 2, p["cf2"] * math.pi / 2]
    effects = [
        f"armature:ia={arm[0]:.6g},{arm[1]:.6g}",
        f"viscous_friction:b={p['b1']:.6g},{p['b2']:.6g}",
        f"coulomb_friction:fc={fc[0]:.6g},{fc[1]:.6g}",
    ]
    return effects, icom


def dfki_model_simple(urdf_in, sid, urdf_out):
    """DFKI's identified simple-pendulum model (system_identification.txt:
    tau = J q'' + m cx g sin q + Fv q' + Fc atan(100 q') + offset) as URDF + effects.
    Only J (about the axis) and m cx enter a one-link model, so the COM is kept at the URDF's
    0.5 m, m = m cx / 0.5 and I_com = J - m 0.5^2. Effects: viscous Fv, Coulomb Fc pi/2, and a
    torque offset of -offset (simgap applies tau_cmd + offset)."""
    # the file declares a default XML namespace: keep it as the default when writing
    ns = ""
    with open(urdf_in) as f:
        head = f.read(1000)
    if 'xmlns="' in head:
        uri = head.split('xmlns="', 1)[1].split('"', 1)[0]
        ET.register_namespace("", uri)
        ns = "{" + uri + "}"
    tree = ET.parse(urdf_in)
    root = tree.getroot()
    link = [l for l in root.findall(ns + "link") if l.find(ns + "inertial") is not None][0]
    inertial = link.find(ns + "inertial")
    z_pub = float(inertial.find(ns + "origin").get("xyz").split()[2])
    c = abs(z_pub)
    m = sid["m*cx"] / c
    icom = sid["J"] - m * c * c
    if icom < 0:
        raise ValueError(f"J - m c^2 = {icom:.5f} < 0")
    inertial.find(ns + "origin").set("xyz", f"0 0 {math.copysign(c, z_pub)!r}")
    inertial.find(ns + "mass").set("value", repr(m))
    it = inertial.find(ns + "inertia")
    for k in ("ixx", "iyy", "izz"):
        it.set(k, repr(icom))
    tree.write(urdf_out)
    effects = [
        f"viscous_friction:b={sid['Fv']:.6g}",
        f"coulomb_friction:fc={sid['Fc'] * math.pi / 2:.6g}",
        f"torque_offset:offset={-sid['offset']:.6g}",
    ]
    return effects, (m, c, icom)


def run(cmd, out_txt):
    t0 = time.monotonic()
    with open(out_txt, "w") as f:
        r = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT)
    dt = time.monotonic() - t0
    if r.returncode != 0:
        with open(out_txt) as f:
            tail = f.read()[-2000:]
        raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}):\n{tail}")
    return dt


def diagnose(args, urdf, fit, held, experiment, tag, export=False):
    """`simgap diagnose`; with `export`, also the corrected model as `TAG.urdf` and `TAG.xml`
    (MJCF) in --out, each with its `.effects.json` sidecar (docs/guide/export.md)."""
    js = os.path.join(args.out, f"{tag}.json")
    cmd = [args.bin, "diagnose", "--urdf", urdf]
    for l in fit:
        cmd += ["--log", l]
    for l in held:
        cmd += ["--holdout", l]
    if experiment:
        cmd += ["--experiment", experiment]
    cmd += ["--json", js]
    if export:
        cmd += ["--export-urdf", os.path.join(args.out, f"{tag}.urdf"), "--export-mjcf", os.path.join(args.out, f"{tag}.xml")]
    if args.reuse and os.path.exists(js):
        with open(js) as f:
            rep = json.load(f)
        return rep, rep.get("_runner_seconds", float("nan"))
    log(f"[{time.strftime('%H:%M:%S')}] diagnose {tag} ...")
    dt = run(cmd, os.path.join(args.out, f"{tag}.txt"))
    with open(js) as f:
        rep = json.load(f)
    rep["_runner_seconds"] = dt
    with open(js, "w") as f:
        json.dump(rep, f)
    log(f"[{time.strftime('%H:%M:%S')}] diagnose {tag}: {dt:.1f} s")
    return rep, dt


def predict(args, urdf, logs, effects, experiment, tag):
    js = os.path.join(args.out, f"{tag}.json")
    cmd = [args.bin, "predict", "--urdf", urdf, "--horizon", HORIZONS]
    for l in logs:
        cmd += ["--log", l]
    for e in effects:
        cmd += ["--effect", e]
    if experiment:
        cmd += ["--experiment", experiment]
    cmd += ["--json", js]
    run(cmd, os.path.join(args.out, f"{tag}.txt"))
    with open(js) as f:
        return json.load(f)


def at(kstep, key, h, hs):
    i = min(range(len(hs)), key=lambda k: abs(hs[k] - h))
    v = kstep[key][i]
    return float("nan") if v is None else v


def run_kstep(ks, held):
    """The k-step figures of one held-out run in a `gap.kstep` layout (and its horizons)."""
    for r in ks.get("runs", []):
        if os.path.abspath(r["log"]) == os.path.abspath(held) or os.path.basename(r["log"]) == os.path.basename(held):
            return r, ks["horizons_s"]
    return ks, ks["horizons_s"]


def fmt(v):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "n/a"
    return f"{v:.4f}"


def fmt_params(e):
    parts = []
    units = e.get("units") or {}
    for k, v in (e.get("parameters") or {}).items():
        u = units.get(k, "") if isinstance(units, dict) else ""
        if isinstance(v, list):
            vs = ", ".join(f"{x:.4g}" if isinstance(x, (int, float)) else str(x) for x in v)
            vs = f"[{vs}]"
        elif isinstance(v, (int, float)):
            vs = f"{v:.4g}"
        else:
            vs = str(v)
        parts.append(f"{k} = {vs}" + (f" {u}" if u and u != "-" else ""))
    return "; ".join(parts)


def effects_text(rep):
    sel = rep.get("selected_effects") or []
    if not sel:
        return "none"
    out = []
    for e in sel:
        joints = ", ".join(e.get("joints") or [])
        out.append(f"`{e.get('effect')}` ({joints}): {fmt_params(e)}")
    return "; ".join(out)


def links_text(rep, urdf):
    """Per corrected link: mass, distance of the centre of mass from the joint axis, m·c, inertia
    about the axis through the centre of mass, and about the joint axis (I_c + m d²), from the
    report's `inertial_error` deltas and the URDF's links."""
    import xml.etree.ElementTree as ET
    import math
    sel = [e for e in rep.get("selected_effects") or [] if e.get("effect") == "inertial_error"]
    if not sel or not urdf:
        return ""
    root = ET.parse(urdf).getroot()
    links = {l.get("name"): l for l in root.findall("link")}
    out = []
    e = sel[0]
    p = e.get("parameters") or {}
    for k, jn in enumerate(e.get("joints") or []):
        j = next((j for j in root.findall("joint") if j.get("name") == jn), None)
        if j is None:
            continue
        ax = [float(x) for x in (j.find("axis").get("xyz") if j.find("axis") is not None else "1 0 0").split()]
        n = math.sqrt(sum(a * a for a in ax))
        ax = [a / n for a in ax]
        inert = links[j.find("child").get("link")].find("inertial")
        o = inert.find("origin")
        if o is not None and any(float(x) != 0.0 for x in (o.get("rpy") or "0 0 0").split()):
            out.append(f"{jn}: rotated inertial frame, not computed")
            continue
        m0 = float(inert.find("mass").get("value"))
        c0 = [float(x) for x in (o.get("xyz") if o is not None else "0 0 0").split()]
        ia = inert.find("inertia").attrib
        i0 = [float(ia.get(x, 0)) for x in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")]
        m = m0 + p["delta_mass"][k]
        c = [a + b for a, b in zip(c0, p["delta_com"][k])]
        i6 = [a + b for a, b in zip(i0, p["delta_inertia"][k])]
        im = [[i6[0], i6[1], i6[2]], [i6[1], i6[3], i6[4]], [i6[2], i6[4], i6[5]]]
        i_axis = sum(ax[r] * im[r][s] * ax[s] for r in range(3) for s in range(3))
        along = sum(a * b for a, b in zip(c, ax))
        d = math.sqrt(max(sum(x * x for x in c) - along * along, 0.0))
        out.append(f"{jn}'s link {m:.3f} kg, centre of mass {d:.3f} m from the axis (m·c {m * d:.3f} kg·m), "
                   f"inertia about the axis {i_axis:.4f} kg·m² through the centre of mass, {i_axis + m * d * d:.4f} kg·m² "
                   f"through the joint")
    return "; ".join(out)


def alternatives_text(rep):
    alts = rep.get("alternatives") or []
    if not alts:
        return "none"
    out = []
    for a in alts:
        if isinstance(a, dict):
            desc = a.get("description") or a.get("reason") or a.get("why") or ""
            what = a.get("effects") or a.get("effect") or a.get("alternative") or ""
            if isinstance(what, list):
                what = " + ".join(w if isinstance(w, str) else json.dumps(w) for w in what)
            out.append(f"{what}: {desc}".strip(": ") if what else (desc or json.dumps(a)))
        else:
            out.append(str(a))
    return "; ".join(out)


def table(title, rows, notes):
    print(f"\n### {title}\n")
    print("| held-out run | fit on | diagnosis [s] | published URDF 0.1 s | +selected 0.1 s | DFKI identified 0.1 s | floor 0.1 s "
          "| published URDF 0.5 s | +selected 0.5 s | DFKI identified 0.5 s | floor 0.5 s |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['held']} | {r['fit']} | {r['secs']:.0f} | " + " | ".join(fmt(x) for x in r["v01"]) + " | "
              + " | ".join(fmt(x) for x in r["v05"]) + " |")
    print()
    print("k-step RMS position error [rad] over all joints at the end of windows of 0.1 s and 0.5 s restarted from the "
          "measured state and driven by the logged torque (replay) or by the re-simulated controller (PD); lower is "
          "better. Floor: constant-velocity extrapolation. Diagnosis: wall-clock seconds of `simgap diagnose`.\n")
    for r in rows:
        links = f" Corrected links: {r['links']}." if r.get("links") else ""
        print(f"- **{r['held']}**: selected: {r['selected']}.{links} Alternatives: {r['alts']}. "
              f"DFKI's corrected URDF alone (its masses and inertias, without its rotor and friction terms): "
              f"{fmt(r['dfki_inertia_only'][0])} / {fmt(r['dfki_inertia_only'][1])} rad at 0.1 / 0.5 s.")
        glitches = [n for n in r["notes"] if ": glitch at t = " in n or "more glitch samples replaced" in n]
        others = [n for n in r["notes"] if n not in glitches]
        print(f"  Verdict: {r['verdict']}." + "".join(f" Note: {n}." for n in others)
              + (" The report lists glitch samples in the fit or held-out logs (see its notes)." if glitches else ""))
    for n in notes:
        print(f"- {n}")


def row(rep, held, dfki_pred, fit_names, held_name, secs, urdf=None):
    k, hs = run_kstep(rep["gap"]["kstep"], held)
    dk, dhs = run_kstep(dfki_pred, held) if dfki_pred else (None, None)
    v = {}
    for h in (0.1, 0.5):
        v[h] = [at(k, "before", h, hs), at(k, "after", h, hs), at(dk, "after", h, dhs) if dk else float("nan"), at(k, "floor", h, hs)]
    inertia_only = [at(dk, "before", h, dhs) for h in (0.1, 0.5)] if dk else [float("nan")] * 2
    return {"held": held_name, "fit": fit_names, "secs": secs, "v01": v[0.1], "v05": v[0.5],
            "selected": effects_text(rep), "links": links_text(rep, urdf), "alts": alternatives_text(rep), "dfki_inertia_only": inertia_only,
            "verdict": rep.get("verdict", ""), "notes": rep.get("notes") or []}


def double_c0(args):
    D = os.path.join(args.data, "dfki-double-pendulum")
    P = os.path.join(D, "system_identification/identified_parameters")
    C = os.path.join(D, "experiment_records/design_C.0/20220914/sys_id")
    urdf = os.path.join(P, "design_C.0/model_3.1/acrobot.urdf")
    exp = os.path.join(HERE, "dfki-c0.experiment.json")
    runs = [os.path.join(C, f"trajectory_0{i}.csv.gz") for i in range(5)]
    notes = []
    # DFKI's identified models for C.0
    try:
        dfki_model_double(urdf, read_yaml_scalars(os.path.join(P, "design_C.0/model_3.0/model_parameters.yml")),
                          os.path.join(args.out, "c0_dfki_model_3.0.urdf"))
    except ValueError as e:
        notes.append(f"DFKI's `model_3.0` (the set the published C.0 URDF carries) cannot be corrected: {e}; "
                     "the table uses `model_h1.0`.")
    dfki_urdf = os.path.join(args.out, "c0_dfki_model_h1.0.urdf")
    dfki_eff, icom = dfki_model_double(urdf, read_yaml_scalars(os.path.join(P, "design_C.0/model_h1.0/model_parameters.yml")), dfki_urdf)
    notes.append(f"DFKI identified model = `model_h1.0`: corrected URDF `{os.path.basename(dfki_urdf)}` "
                 f"(COM inertias {icom[0]:.5f}, {icom[1]:.5f} kg·m²) + `" + "` + `".join(dfki_eff) + "`.")
    rows = []
    for i in range(5):
        fit = [r for j, r in enumerate(runs) if j != i]
        rep, secs = diagnose(args, urdf, fit, [runs[i]], exp, f"c0_hold{i}", export=True)
        dp = predict(args, dfki_urdf, [runs[i]], dfki_eff, exp, f"c0_hold{i}_dfki")
        rows.append(row(rep, runs[i], dp, ", ".join(f"0{j}" for j in range(5) if j != i), f"trajectory_0{i}", secs, urdf))
    table("Double pendulum C.0 (open loop, leave one run out)", rows, notes)
    return rows


def double_a0(args):
    D = os.path.join(args.data, "dfki-double-pendulum")
    P = os.path.join(D, "system_identification/identified_parameters")
    urdf = os.path.join(P, "design_A.0/model_2.1/pendubot.urdf")
    exp = os.path.join(HERE, "dfki-a0.experiment.json")
    a0 = os.path.join(args.out, "a0")
    os.makedirs(a0, exist_ok=True)
    subprocess.run([sys.executable, os.path.join(HERE, "split_a0.py"), D, a0], check=True, stdout=sys.stderr)
    fit, held = os.path.join(a0, "a0_first_half.csv"), os.path.join(a0, "a0_second_half.csv")
    dfki_urdf = os.path.join(args.out, "a0_dfki_model_2.0.urdf")
    dfki_eff, icom = dfki_model_double(urdf, read_yaml_scalars(os.path.join(P, "design_A.0/model_2.0/model_parameters.yml")), dfki_urdf)
    rep, secs = diagnose(args, urdf, [fit], [held], exp, "a0")
    dp = predict(args, dfki_urdf, [held], dfki_eff, exp, "a0_dfki")
    notes = [f"DFKI identified model = `model_2.0`: corrected URDF (COM inertias {icom[0]:.5f}, {icom[1]:.5f} kg·m²) + `"
             + "` + `".join(dfki_eff) + "`. The re-simulated PD controller (Kp 20, Kd 0.6) closes the loop in every window."]
    rows = [row(rep, held, dp, "first half (0–37.5 s)", "second half (37.5–75 s)", secs, urdf)]
    table("Double pendulum A.0 (PD tracking, time split)", rows, notes)
    return rows


def simple(args):
    S = os.path.join(args.data, "dfki-simple-pendulum")
    urdf = os.path.join(S, "urdf/simplependul_dfki_pino_Modi.urdf")
    sp = os.path.join(args.out, "sp")
    os.makedirs(sp, exist_ok=True)
    # Per-log experiments through sidecars: the two records differ in sample period. The logs are
    # copied (outside the repository) so the sidecars can sit next to them.
    recs = {
        "pd": ("control_method_pd/system_identification/data_measured.csv.gz", 0.003334,
               "PD system-identification record (motor-internal PD), replay of the torque the motor reports"),
        "gravcomp": ("control_method_gravity_compensation/data_measured.csv.gz", 0.001,
                     "gravity compensation while the pendulum is moved by hand, replay of the torque the motor reports"),
    }
    paths = {}
    for k, (rel, dt, note) in recs.items():
        dst = os.path.join(sp, f"sp_{k}.csv.gz")
        shutil.copyfile(os.path.join(S, rel), dst)
        with open(os.path.join(sp, f"sp_{k}.experiment.json"), "w") as f:
            json.dump({"controller": "replay", "joints": "shoulder", "kp": "0", "kv": "0",
                       "sample_period": str(dt), "note": note}, f, indent=1)
        paths[k] = dst
    sid = read_sysid_txt(os.path.join(S, "control_method_pd/system_identification/system_identification.txt"))
    dfki_urdf = os.path.join(args.out, "sp_dfki_sysid.urdf")
    dfki_eff, (m, c, icom) = dfki_model_simple(urdf, sid, dfki_urdf)
    rows = []
    for held, fitk in (("gravcomp", "pd"), ("pd", "gravcomp")):
        rep, secs = diagnose(args, urdf, [paths[fitk]], [paths[held]], None, f"sp_hold_{held}")
        dp = predict(args, dfki_urdf, [paths[held]], dfki_eff, None, f"sp_hold_{held}_dfki")
        rows.append(row(rep, paths[held], dp, recs[fitk][0].split("/")[0], recs[held][0].split("/")[0], secs))
    notes = [f"DFKI identified model = `system_identification.txt`: J = {sid['J']:.4g} kg·m², m·c = {sid['m*cx']:.4g} kg·m "
             f"as a URDF with m = {m:.4f} kg at c = {c} m, COM inertia {icom:.5f} kg·m², + `" + "` + `".join(dfki_eff) + "`."]
    table("Simple pendulum (replay of the motor's torque; each record held out once)", rows, notes)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default="../shared/data")
    ap.add_argument("--bin", default="target/release/simgap")
    ap.add_argument("--out", default="/tmp/cs")
    ap.add_argument("--only", choices=["c0", "a0", "simple"], action="append", help="run only these data sets")
    ap.add_argument("--reuse", action="store_true", help="reuse diagnosis JSONs already in --out")
    args = ap.parse_args()
    args.out = os.path.abspath(args.out)
    os.makedirs(args.out, exist_ok=True)
    ver = subprocess.run([args.bin, "--version"], capture_output=True, text=True).stdout.strip()
    built = time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime(os.path.getmtime(args.bin)))
    print(f"# simgap case study, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {ver} ({args.bin}, built {built})")
    only = args.only or ["c0", "a0", "simple"]
    if "c0" in only:
        double_c0(args)
    if "a0" in only:
        double_a0(args)
    if "simple" in only:
        simple(args)


if __name__ == "__main__":
    main()
