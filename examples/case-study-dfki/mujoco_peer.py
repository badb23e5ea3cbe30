#!/usr/bin/env python3
"""MuJoCo's system-identification toolbox as a peer on the DFKI double pendulum C.0 runs.

Run by hand (not part of the test suite), in a throwaway virtual environment:

    python3 -m venv /tmp/mjvenv && /tmp/mjvenv/bin/pip install "mujoco[sysid]"
    /tmp/mjvenv/bin/python examples/case-study-dfki/mujoco_peer.py --data ../shared/data \
        --bin target/release/simgap --out /tmp/cs/mj

For each of the five leave-one-run-out folds of `run.py` (fit on four of trajectory_00..04, hold
out the fifth) it fits, with the toolbox's defaults (Gauss-Newton on the simulated sensor
residual of whole runs, `optimizer="mujoco"`), 26 parameters on the published URDF compiled by
MuJoCo: the inertia of both links in the pseudo-inertia parameterisation (10 each, physically
consistent by construction, default bounds), and damping, friction loss and armature per joint.
`--chunk S` instead cuts every fit run into S-second pieces started from the measured state
(closer to the k-step measure; not the default).

The fitted model is then written as a URDF (mass, centre of mass and full inertia of each link
as MuJoCo holds them) plus simgap effects (armature, viscous_friction = damping,
coulomb_friction = friction loss; MuJoCo's friction loss is a dry-friction constraint, simgap's
Coulomb term is fc·tanh(q̇/0.01)), and `simgap predict` scores it on the held-out run with the
same k-step windows as the case study. Everything is written under --out, nothing into the
repository.
"""
import argparse
import csv
import gzip
import json
import os
import re
import subprocess
import sys
import time

import numpy as np
import mujoco
from mujoco import sysid

JOINTS = ["Joint1", "Joint2"]
LINKS = ["Link1", "Link2"]


def load_run(path):
    with gzip.open(path, "rt") as f:
        r = csv.reader(f)
        h = next(r)
        d = np.array([[float(x) for x in row] for row in r])
    c = {k: i for i, k in enumerate(h)}
    t = d[:, c["time"]] - d[0, c["time"]]
    q = d[:, [c["pos_meas1"], c["pos_meas2"]]]
    v = d[:, [c["vel_meas1"], c["vel_meas2"]]]
    u = d[:, [c["tau_con1"], c["tau_con2"]]]
    return t, q, v, u


def make_spec(urdf_path, timestep):
    s = open(urdf_path).read()
    # MuJoCo's URDF reader rejects the fixed joint to the undefined link 'world' and would look
    # for the (absent) meshes: drop both, they carry no dynamics
    s = re.sub(r'<joint name="base_weld".*?</joint>', "", s, flags=re.S)
    s = re.sub(r"<visual>.*?</visual>", "", s, flags=re.S)
    spec = mujoco.MjSpec.from_string(s)
    spec.option.timestep = timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_RK4
    for j in JOINTS:
        spec.joint(j).limited = mujoco.mjtLimited.mjLIMITED_FALSE
        spec.joint(j).actfrclimited = mujoco.mjtLimited.mjLIMITED_FALSE
        a = spec.add_actuator(name=f"{j}_motor", target=j, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
    for j in JOINTS:
        spec.add_sensor(name=f"{j}_pos", type=mujoco.mjtSensor.mjSENS_JOINTPOS, objtype=mujoco.mjtObj.mjOBJ_JOINT, objname=j)
    for j in JOINTS:
        spec.add_sensor(name=f"{j}_vel", type=mujoco.mjtSensor.mjSENS_JOINTVEL, objtype=mujoco.mjtObj.mjOBJ_JOINT, objname=j)
    return spec


def sequences(spec, model, runs, chunk):
    names, states, ctrls, sens = [], [], [], []
    for path in runs:
        t, q, v, u = load_run(path)
        if chunk > 0:
            n = len(t)
            starts = []
            s0 = 0
            while s0 < n:
                e = np.searchsorted(t, t[s0] + chunk)
                if e - s0 > 10 and t[min(e, n - 1)] - t[s0] >= 0.9 * chunk:
                    starts.append((s0, e))
                s0 = e
        else:
            starts = [(0, len(t))]
        for a, b in starts:
            tt = t[a:b] - t[a]
            names.append(f"{os.path.basename(path)}@{t[a]:.2f}")
            states.append(sysid.create_initial_state(model, q[a], v[a]))
            ctrls.append(sysid.TimeSeries.from_control_names(tt, u[a:b], model))
            sens.append(sysid.TimeSeries.from_names(tt, np.hstack([q[a:b], v[a:b]]), model))
    return sysid.ModelSequences("dfki_c0", spec, names, states, ctrls, sens)


def set_joint(spec, joint, attr, value):
    field = getattr(spec.joint(joint), attr)
    if hasattr(field, "__len__"):
        field[0] = value  # damping is an array in MuJoCo 4
    else:
        setattr(spec.joint(joint), attr, value)


def apply_theta(spec, body_name, theta):
    """The toolbox's pseudo-inertia modifier without its compile step: that step sets
    `compiler.inertiafromgeom = 2`, which on a model without geoms (a URDF whose meshes are
    absent) zeroes the inertia of the other link and fails to compile ("mass and inertia of moving
    bodies must be larger than mjMINVAL"), and its NaN iquat fails the same way."""
    from mujoco.sysid._src import model_modifier as mm
    spec.compiler.inertiafromgeom = 0
    pi = mm.pi_from_theta(np.asarray(theta))
    body = spec.body(body_name)
    body.explicitinertial = True
    body.mass = pi[0]
    body.ipos = pi[1:4] / pi[0]
    sk = mm.skew(body.ipos)
    full = pi[4:].reshape(3, 3) + pi[0] * sk @ sk
    body.inertia[:] = 0.0
    body.iquat[:] = [1.0, 0.0, 0.0, 0.0]  # the URDF reader's layout: fullinertia, zero inertia, unit iquat
    body.fullinertia[:] = [full[0, 0], full[1, 1], full[2, 2], full[0, 1], full[0, 2], full[1, 2]]


def parameters(spec, model):
    params = sysid.ParameterDict()
    for link in LINKS:
        params.add(sysid.body_inertia_param(spec, model, link, inertia_type=sysid.InertiaType.Pseudo,
                                            modifier=lambda s, p, link=link: apply_theta(s, link, p.value)))
    spec.compiler.inertiafromgeom = 0
    for j in JOINTS:
        for attr, hi in (("damping", 1.0), ("frictionloss", 1.0), ("armature", 0.1)):
            params.add(sysid.Parameter(f"{j}_{attr}", 0.0, 0.0, hi,
                                       modifier=lambda s, p, j=j, attr=attr: set_joint(s, j, attr, p.value[0])))
    return params


def export(spec, params, urdf_in, urdf_out):
    """The fitted model as URDF inertials + simgap effects."""
    s2 = spec.copy() if hasattr(spec, "copy") else spec
    for p in params.values():
        p.apply_modifier(s2)
    m = s2.compile()
    text = open(urdf_in).read()
    out = {}
    for link in LINKS:
        b = m.body(link)
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, b.iquat)
        R = R.reshape(3, 3)
        I = R @ np.diag(b.inertia) @ R.T
        ipos = [float(x) for x in b.ipos]
        I = [[float(x) for x in row] for row in I]
        mass = float(b.mass[0])
        inertial = (f'<inertial>\n      <origin xyz="{ipos[0]!r} {ipos[1]!r} {ipos[2]!r}" rpy="0 0 0" />\n'
                    f'      <mass value="{mass!r}" />\n'
                    f'      <inertia ixx="{I[0][0]!r}" ixy="{I[0][1]!r}" ixz="{I[0][2]!r}" iyy="{I[1][1]!r}" iyz="{I[1][2]!r}" izz="{I[2][2]!r}" />\n'
                    f'    </inertial>')
        text = re.sub(rf'(<link name="{link}">\s*)<inertial>.*?</inertial>', lambda mm: mm.group(1) + inertial, text, flags=re.S)
        out[link] = {"mass": mass, "com": [float(x) for x in ipos], "inertia_about_com_axis": I[0][0]}
    with open(urdf_out, "w") as f:
        f.write(text)
    val = lambda k: float(params[k].value[0])
    arm = [val(f"{j}_armature") for j in JOINTS]
    damp = [val(f"{j}_damping") for j in JOINTS]
    fl = [val(f"{j}_frictionloss") for j in JOINTS]
    effects = [f"armature:ia={arm[0]:.6g},{arm[1]:.6g}", f"viscous_friction:b={damp[0]:.6g},{damp[1]:.6g}",
               f"coulomb_friction:fc={fl[0]:.6g},{fl[1]:.6g}"]
    out.update({"armature": arm, "damping": damp, "frictionloss": fl})
    return effects, out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default="../shared/data")
    ap.add_argument("--bin", default="target/release/simgap")
    ap.add_argument("--out", default="/tmp/cs/mj")
    ap.add_argument("--folds", default="0,1,2,3,4")
    ap.add_argument("--chunk", type=float, default=0.0, help="fit on pieces of S seconds (0: whole runs, the default)")
    ap.add_argument("--max-iters", type=int, default=100)
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    D = os.path.join(args.data, "dfki-double-pendulum")
    urdf = os.path.join(D, "system_identification/identified_parameters/design_C.0/model_3.1/acrobot.urdf")
    C = os.path.join(D, "experiment_records/design_C.0/20220914/sys_id")
    runs = [os.path.join(C, f"trajectory_0{i}.csv.gz") for i in range(5)]
    exp = os.path.join(os.path.dirname(os.path.abspath(__file__)), "dfki-c0.experiment.json")
    print(f"# MuJoCo {mujoco.__version__} sysid peer, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
          f"chunk = {args.chunk or 'whole runs'}")
    print("\n| held-out run | fit [s] | published URDF 0.1 s | MuJoCo sysid 0.1 s | published URDF 0.5 s | MuJoCo sysid 0.5 s |")
    print("|---|---:|---:|---:|---:|---:|")
    summary = []
    for i in [int(x) for x in args.folds.split(",")]:
        fit = [r for j, r in enumerate(runs) if j != i]
        spec = make_spec(urdf, 0.002)
        model = spec.compile()
        params = parameters(spec, model)
        ms = sequences(spec, model, fit, args.chunk)
        resid = sysid.build_residual_fn(models_sequences=[ms])
        t0 = time.monotonic()
        opt, res = sysid.optimize(initial_params=params, residual_fn=resid, optimizer="mujoco", verbose=False,
                                  max_iters=args.max_iters)
        secs = time.monotonic() - t0
        try:
            r_star, _, _ = resid(opt.as_vector(), opt)
            _, intervals = sysid.calculate_intervals(r_star, res.jac)
            intervals = [float(x) for x in intervals]
        except Exception as e:  # intervals are informative only
            intervals = f"not computed: {e}"
        urdf_out = os.path.join(args.out, f"c0_hold{i}_mujoco.urdf")
        effects, fitted = export(spec, opt, urdf, urdf_out)
        js = os.path.join(args.out, f"c0_hold{i}_mujoco_predict.json")
        cmd = [args.bin, "predict", "--urdf", urdf_out, "--log", runs[i], "--horizon", "0.1,0.5", "--experiment", exp, "--json", js]
        for e in effects:
            cmd += ["--effect", e]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        after = json.load(open(js))["after"]
        js0 = os.path.join(args.out, f"c0_hold{i}_published_predict.json")
        subprocess.run([args.bin, "predict", "--urdf", urdf, "--log", runs[i], "--horizon", "0.1,0.5", "--experiment", exp,
                        "--json", js0], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        before = json.load(open(js0))["before"]
        print(f"| trajectory_0{i} | {secs:.0f} | {before[0]:.4f} | {after[0]:.4f} | {before[1]:.4f} | {after[1]:.4f} |", flush=True)
        summary.append({"held_out": f"trajectory_0{i}", "fit_seconds": secs, "before": before, "after": after,
                        "effects": effects, "fitted": fitted, "names": opt.keys(),
                        "values": [list(map(float, p.value)) for p in opt.values()], "intervals_95": intervals,
                        "cost": float(getattr(res, "cost", float("nan")) if np.isscalar(getattr(res, "cost", None)) else float("nan"))})
        with open(os.path.join(args.out, "mujoco_peer.json"), "w") as f:
            json.dump(summary, f, indent=1)
    print()
    for s in summary:
        f = s["fitted"]
        print(f"- {s['held_out']} held out: Link1 m = {f['Link1']['mass']:.3f} kg, COM {np.round(f['Link1']['com'], 3).tolist()} m, "
              f"I_xx(COM) = {f['Link1']['inertia_about_com_axis']:.4f}; Link2 m = {f['Link2']['mass']:.3f} kg, "
              f"COM {np.round(f['Link2']['com'], 3).tolist()} m, I_xx(COM) = {f['Link2']['inertia_about_com_axis']:.4f} kg·m²; "
              f"armature {np.round(f['armature'], 5).tolist()} kg·m², damping {np.round(f['damping'], 4).tolist()} N·m·s/rad, "
              f"friction loss {np.round(f['frictionloss'], 4).tolist()} N·m")


if __name__ == "__main__":
    main()
