#!/usr/bin/env python3
"""SO-101 case study: the published MJCF, an optimiser-tuned MJCF, simgap's corrected model and
constant velocity, predicting the same held-out windows of a real SO-101 arm
(docs/results/case-study-so101.md).

    python3 -m venv .venv-cs && .venv-cs/bin/pip install numpy scipy mujoco pyarrow
    .venv-cs/bin/python examples/case-study-so101/compare.py --fit 4 --holdout 14,24,31,37 \
        --simgap /path/to/simgap [--report R.json] --json out.json

Data: SAGE's SO-101 recordings as a LeRobot v3.0 dataset, read from --data (default
../shared/data/sage-so101 next to the repository; never copied into it). Episodes are the
dataset's indices. Positions are degrees (meta/info.json, README): they become radians as
simgap's LeRobot reader makes them (value · π/180), times are frame_index / fps. The gripper is
range-normalised 0–100 without a calibration file: every model holds it at its zero (simgap
locks the joint; the MJCF here has the gripper joint and actuator removed, the jaw welded at 0).

The figures are simgap's (docs/method/how-far.md, crates/simgap-diag/src/prediction/kstep.rs and
prepare/windows.rs), laid here from the same inputs:

  * glitch repair as prepare/robust.rs (counted; none are expected on encoder data);
  * restart state: simgap's smoothing differentiator (local cubic least squares over ±3 samples
    at 50 Hz, PrepareOptions::default().window = 0.05 s) for q̂ and q̂̇, the same for every
    model; windows on its valid range, every max(0.1 s, period, span/200) (a 120 s run has 200
    windows, 0.6 s apart; fit runs for the optimiser 48, as simgap scores its fit runs);
  * the end of horizon h: the first sample at or after t0 + h − T/2; the error there is the
    simulated minus the logged position, capped at π per joint;
  * the k-step figure is sqrt(mean over windows of Σ_joints e²) [rad], pooled over runs (so it
    is √5 × the RMS over windows and joints); per joint, the RMS over windows;
  * whole episode: simulated from the first sample (the logged position, the velocity a
    forward difference as simgap's re-simulation takes it: every run starts at rest) with the
    logged goals held per sample; mean |error| over samples and joints, averaged over runs (as
    `simgap predict` prints it).

When simgap rows are asked for, the windows laid here are checked against the window starts and
restart states `simgap predict --json` lists, and the constant-velocity figure against simgap's
`floor`: equal figures mean equal windows, states and measured positions.

Rows: (a) the MJCF as published (so101_new_calib.xml, mesh geoms stripped, MuJoCo's Euler step
of 2 ms, ten steps per 20 ms sample, position actuators with ctrl = the logged goal);
(b) the same MJCF with kp, kv (actuator damping), joint damping, frictionloss and armature per
arm joint fitted by scipy's least_squares on the fit episodes' k-step errors; (c) simgap's
corrected model (`simgap predict` with the diagnosis report's selected effects); simgap nominal
(`simgap predict` without effects: the URDF plus the servo law of the experiment file);
(d) constant-velocity extrapolation q̂ + q̂̇ h; (e) the goal as the prediction (q = the goal in
force at the end sample), a reference that needs no model. Two rows check that MuJoCo and simgap
agree on one model: (s) the MJCF's bodies with simgap's nominal servo law (kp = kt/R·V·duty_gain,
the clipped force, the back-EMF as joint damping, the goal rate limit), and (z) the same with the
torque computed at each logged sample and held over it, as simgap's law holds the duty.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
DEFAULT_DATA = REPO.parent / "shared" / "data" / "sage-so101"
ARM = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"]
HORIZONS = (0.1, 0.25, 0.5)
WINDOW_S = 0.05  # PrepareOptions::default().window
MAX_WINDOWS = 200  # windows::MAX_WINDOWS_PER_RUN (held-out runs)
FIT_WINDOWS = 48  # windows::FIT_WINDOWS_PER_RUN (fit runs)
CAP = math.pi
PARAMS = ["kp", "kv", "damping", "frictionloss", "armature"]
# log10 bounds of the optimiser per parameter
BOUNDS = {"kp": (0.0, 3.5), "kv": (-3.0, 1.5), "damping": (-3.0, 1.0), "frictionloss": (-3.0, 0.3), "armature": (-3.0, -0.3)}
ROWS = ["a", "b", "c", "nominal", "s", "z", "d", "e"]
LABELS = {
    "a": "(a) MJCF as published",
    "b": "(b) MJCF, optimiser-fitted",
    "c": "(c) simgap corrected",
    "nominal": "simgap nominal",
    "s": "MuJoCo, simgap's nominal servo law",
    "z": "MuJoCo, same, duty held per sample",
    "d": "(d) constant velocity",
    "e": "(e) goal as prediction",
}


# ---------------------------------------------------------------------------------------------
# data


class Episode:
    """One LeRobot episode: times, arm positions and goals [rad], prepared for k-step windows."""

    def __init__(self, index: int, name: str, t: np.ndarray, q: np.ndarray, goal: np.ndarray, period: float):
        self.index, self.name, self.t, self.q, self.goal, self.period = index, name, t, q, goal, period
        self.glitches = repair_glitches(self.t, self.q)
        self.q_hat, self.qd_hat, self.valid = smooth(self.t, self.q)

    def windows(self, max_windows: int, horizons=HORIZONS):
        """(start sample, [end sample or None per horizon]) as windows.rs lays them."""
        t, valid = self.t, self.valid
        if len(valid) == 0:
            return []
        stride = max(min(horizons), self.period)
        span = t[valid[-1]] - t[valid[0]]
        stride = max(stride, span / max(max_windows, 1))
        out, next_t = [], t[valid[0]]
        for k in valid:
            if t[k] + 1e-12 < next_t:
                continue
            next_t = t[k] + stride
            ends = []
            for h in horizons:
                j = int(np.searchsorted(t, t[k] + h - 0.5 * self.period, side="left"))
                ends.append(j if j < valid.stop and h > 0 else None)
            if all(e is None for e in ends):
                break
            out.append((k, ends))
        return out


def read_episodes(folder: Path, indices: list[int], max_seconds: float | None) -> list[Episode]:
    import pyarrow.parquet as pq

    info = json.loads((folder / "meta" / "info.json").read_text())
    fps = float(info["fps"])
    names = info["features"]["observation.state"]["names"]
    anames = info["features"]["action"]["names"]
    cols = [names.index(f"{j}.pos") for j in ARM]
    acols = [anames.index(f"{j}.pos") for j in ARM]
    meta = pq.read_table(folder / "meta" / "episodes" / "chunk-000" / "file-000.parquet", columns=["episode_index", "tasks", "length", "data/chunk_index", "data/file_index"]).to_pylist()
    by_index = {m["episode_index"]: m for m in meta}
    out = []
    deg = math.pi / 180.0  # simgap's LeRobot reader: degrees · π/180
    for i in indices:
        if i not in by_index:
            raise SystemExit(f"episode {i}: not in {folder} (episodes {min(by_index)}–{max(by_index)})")
        m = by_index[i]
        path = folder / info["data_path"].format(chunk_index=m["data/chunk_index"], file_index=m["data/file_index"])
        table = pq.read_table(path, columns=["observation.state", "action", "frame_index", "episode_index"], filters=[("episode_index", "=", i)])
        table = table.sort_by("frame_index")
        if table.num_rows != m["length"]:
            raise SystemExit(f"episode {i}: {table.num_rows} frames in {path}, the metadata says {m['length']}")
        frame = table.column("frame_index").to_numpy().astype(np.float64)
        state = np.asarray(table.column("observation.state").combine_chunks().flatten().to_numpy(), dtype=np.float32).reshape(-1, len(names))
        action = np.asarray(table.column("action").combine_chunks().flatten().to_numpy(), dtype=np.float32).reshape(-1, len(anames))
        t = frame / fps
        q = state[:, cols].astype(np.float64) * deg
        goal = action[:, acols].astype(np.float64) * deg
        if max_seconds is not None:
            keep = t < t[0] + max_seconds
            t, q, goal = t[keep], q[keep], goal[keep]
        out.append(Episode(i, m["tasks"][0], t, q, goal, 1.0 / fps))
    return out


def repair_glitches(t: np.ndarray, q: np.ndarray) -> list[tuple[int, int]]:
    """prepare/robust.rs: a sample far from the midpoint of its neighbours (beyond 50 robust σ
    of that distance, the neighbours' own step, and max(1000 Δt²/4, 1 mrad, 5 encoder steps))
    is replaced by the midpoint. In place; returns (sample, joint) of each repair."""
    found = []
    rows = len(t)
    if rows < 9:
        return found
    for j in range(q.shape[1]):
        x = q[:, j].copy()
        d = np.zeros(rows)
        d[1:-1] = x[1:-1] - 0.5 * (x[:-2] + x[2:])
        sigma = 1.4826 * np.sort(np.abs(d))[rows // 2]
        inc = np.abs(np.diff(x))
        step = inc[inc > 0].min() if np.any(inc > 0) else 0.0
        dt = t[2:] - t[:-2]
        floor = np.maximum(np.maximum(1000.0 * dt * dt / 4.0, 1e-3), 5.0 * step)
        bad = (np.abs(d[1:-1]) > np.maximum(50.0 * sigma, floor)) & (np.abs(d[1:-1]) > np.abs(x[2:] - x[:-2]))
        for k in np.nonzero(bad)[0] + 1:
            q[k, j] = 0.5 * (x[k - 1] + x[k + 1])
            found.append((int(k), j))
    return found


def smooth(t: np.ndarray, q: np.ndarray, window: float = WINDOW_S):
    """prepare/differentiate.rs: value and first derivative of a cubic least-squares fit over
    ±half samples (time scaled by half the window's span); one set of weights on uniform
    stamps. Returns q̂, q̂̇ (0 outside the valid range) and the valid range."""
    n = len(t)
    dt = (t[-1] - t[0]) / (n - 1) if n > 1 else 1.0
    half = min(max(math.floor(window / dt / 2.0 + 0.5), 3), 200)
    valid = range(half, n - half) if n > 2 * half else range(0)
    q_hat, qd_hat = np.zeros_like(q), np.zeros_like(q)
    if len(valid) == 0:
        return q_hat, qd_hat, valid
    uniform = np.all(np.abs(np.diff(t) - dt) <= 1e-3 * dt)

    def weights(k):
        scale = (t[k + half] - t[k - half]) / 2.0
        s = (t[k - half:k + half + 1] - t[k]) / scale
        a = np.vander(s, 4, increasing=True)
        w = np.linalg.inv(a.T @ a) @ a.T
        return w[0], w[1] / scale

    if uniform:
        w0, w1 = weights(half)
        from numpy.lib.stride_tricks import sliding_window_view

        for j in range(q.shape[1]):
            seg = sliding_window_view(q[:, j], 2 * half + 1)  # row i: samples i .. i+2h
            q_hat[half:n - half, j] = seg @ w0
            qd_hat[half:n - half, j] = seg @ w1
    else:
        for k in valid:
            w0, w1 = weights(k)
            seg = q[k - half:k + half + 1]
            q_hat[k], qd_hat[k] = w0 @ seg, w1 @ seg
    return q_hat, qd_hat, valid


# ---------------------------------------------------------------------------------------------
# figures


def capped(e: np.ndarray) -> np.ndarray:
    return np.minimum(np.where(np.isfinite(e), np.abs(e), CAP), CAP)


def figures(errors: list[np.ndarray]) -> dict:
    """errors: per run, an array (windows, horizons, joints), NaN where a horizon is past the
    run. Pooled: per horizon sqrt(mean over windows of ‖e‖²); per joint: RMS over windows."""
    e = np.concatenate(errors, axis=0)
    nh = e.shape[1]
    pooled, per_joint = [], []
    for h in range(nh):
        rows = e[:, h, :]
        ok = np.all(np.isfinite(rows), axis=1)
        pooled.append(float(np.sqrt(np.mean(np.sum(rows[ok] ** 2, axis=1)))) if ok.any() else float("nan"))
        per_joint.append([float(np.sqrt(np.mean(rows[ok, j] ** 2))) if ok.any() else float("nan") for j in range(e.shape[2])])
    return {"kstep": pooled, "per_joint": [list(x) for x in zip(*per_joint)], "windows": int(e.shape[0])}


def row(errors: list[np.ndarray], whole: list[float]) -> dict:
    """A table row: pooled figures, and per held-out run its k-step figures and whole-episode
    error."""
    r = figures(errors)
    r["per_run"] = [figures([e])["kstep"] for e in errors]
    r["per_run_per_joint"] = [figures([e])["per_joint"] for e in errors]
    r["whole_per_run"] = [float(w) for w in whole]
    r["whole"] = float(np.mean(whole))
    return r


def floor_errors(ep: Episode, wins) -> np.ndarray:
    out = np.full((len(wins), len(HORIZONS), len(ARM)), np.nan)
    for w, (k0, ends) in enumerate(wins):
        for h, k1 in enumerate(ends):
            if k1 is not None:
                out[w, h] = capped(ep.q_hat[k0] + ep.qd_hat[k0] * (ep.t[k1] - ep.t[k0]) - ep.q[k1])
    return out


def goal_errors(ep: Episode, wins) -> np.ndarray:
    out = np.full((len(wins), len(HORIZONS), len(ARM)), np.nan)
    for w, (k0, ends) in enumerate(wins):
        for h, k1 in enumerate(ends):
            if k1 is not None:
                out[w, h] = capped(ep.goal[k1] - ep.q[k1])
    return out


# ---------------------------------------------------------------------------------------------
# MuJoCo


def load_mjcf(path: Path):
    """The published MJCF with its mesh assets and mesh geoms removed (the files are not
    shipped; every body has an explicit <inertial>), and the gripper joint and actuator
    removed (the jaw welded at its zero). Returns (MjModel, the file's inertials by body)."""
    import mujoco

    tree = ET.parse(path)
    root = tree.getroot()
    for parent in root.iter():
        for child in list(parent):
            mesh_geom = child.tag == "geom" and (child.get("type") == "mesh" or child.get("mesh"))
            mesh_asset = child.tag == "mesh" and parent.tag == "asset"
            gripper = (child.tag == "joint" and child.get("name") == "gripper") or (parent.tag == "actuator" and child.get("joint") == "gripper")
            if mesh_geom or mesh_asset or gripper:
                parent.remove(child)
    inertials = {}
    for body in root.iter("body"):
        i = body.find("inertial")
        if i is not None:
            inertials[body.get("name")] = (float(i.get("mass")), [float(x) for x in i.get("pos").split()], [float(x) for x in i.get("fullinertia").split()])
    m = mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode"))
    # a diverged simulation runs on to NaN (counted as π, as simgap counts a diverged window)
    # instead of MuJoCo's silent reset to the home pose
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(m.njnt)]
    if names != ARM or m.nu != len(ARM) or [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a) for a in range(m.nu)] != ARM:
        raise SystemExit(f"{path}: joints {names}; expected {ARM} once the gripper is removed")
    return m, inertials


def check_inertials(m, inertials) -> float:
    """Largest difference between the masses, principal inertias (relative) and centres of mass
    (m) MuJoCo holds and the file's <inertial> elements, over every body (the welded jaw keeps
    its own body)."""
    import mujoco

    worst = 0.0
    for b in range(1, m.nbody):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b)
        mass, pos, full = inertials[name]
        worst = max(worst, abs(m.body_mass[b] - mass) / mass)
        xx, yy, zz, xy, xz, yz = full
        eig = np.sort(np.linalg.eigvalsh(np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])))
        worst = max(worst, float(np.max(np.abs(np.sort(m.body_inertia[b]) - eig) / eig.max())))
        worst = max(worst, float(np.max(np.abs(m.body_ipos[b] - pos))))
    return worst


def get_params(m) -> dict:
    return {
        "kp": m.actuator_gainprm[:, 0].copy(),
        "kv": -m.actuator_biasprm[:, 2].copy(),
        "damping": m.dof_damping.copy(),
        "frictionloss": m.dof_frictionloss.copy(),
        "armature": m.dof_armature.copy(),
    }


def set_params(m, p: dict) -> None:
    m.actuator_gainprm[:, 0] = p["kp"]
    m.actuator_biasprm[:, 1] = -np.asarray(p["kp"])
    m.actuator_biasprm[:, 2] = -np.asarray(p["kv"])
    m.dof_damping[:] = p["damping"]
    m.dof_frictionloss[:] = p["frictionloss"]
    m.dof_armature[:] = p["armature"]


class MjWindows:
    """The k-step windows of some episodes as one batch of MuJoCo rollouts: restart states,
    goals per step (zero-order hold, ten 2 ms steps per 20 ms sample) and where each horizon
    ends."""

    def __init__(self, m, episodes: list[Episode], max_windows: int, rate_limit: float | None = None):
        import mujoco

        self.runs = []
        d = mujoco.MjData(m)
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        nstate = mujoco.mj_stateSize(m, spec)
        states, ctrls, ends = [], [], []
        for ep in episodes:
            wins = ep.windows(max_windows)
            sub = steps_per_sample(m, ep)
            longest = max(max(e for e in ends_ if e is not None) - k0 for k0, ends_ in wins)
            for k0, ends_ in wins:
                mujoco.mj_resetData(m, d)
                d.qpos[:] = ep.q_hat[k0]
                d.qvel[:] = ep.qd_hat[k0]
                s = np.empty(nstate)
                mujoco.mj_getState(m, d, s, spec)
                states.append(s)
                k = np.minimum(np.arange(k0, k0 + longest), len(ep.t) - 1)
                ctrls.append(np.repeat(rate_limited(ep.goal[k], ep.t[k], rate_limit), sub, axis=0))
                ends.append([None if e is None else (e - k0) * sub - 1 for e in ends_])
            self.runs.append((ep, wins, len(wins)))
        self.states = np.array(states)
        self.ctrls = np.array(ctrls)
        self.ends = ends
        self.spec = spec
        self.data = d

    def errors(self, m) -> list[np.ndarray]:
        """Per run, (windows, horizons, joints) errors of model `m` (capped; NaN past the run)."""
        from mujoco import rollout

        state, _ = rollout.rollout(m, self.data, self.states, self.ctrls)
        qpos = state[:, :, 1:1 + m.nq]
        out, w0 = [], 0
        for ep, wins, nw in self.runs:
            e = np.full((nw, len(HORIZONS), len(ARM)), np.nan)
            for w in range(nw):
                _, ends_ = wins[w]
                for h, (k1, s) in enumerate(zip(ends_, self.ends[w0 + w])):
                    if k1 is not None:
                        e[w, h] = capped(qpos[w0 + w, s] - ep.q[k1])
            out.append(e)
            w0 += nw
        return out


def rate_limited(goal: np.ndarray, t: np.ndarray, rate: float | None) -> np.ndarray:
    """The goals moved at most `rate`·Δt per sample from the first (no limit: as logged)."""
    if rate is None:
        return goal
    out = goal.copy()
    for i in range(1, len(goal)):
        step = rate * (t[i] - t[i - 1])
        out[i] = out[i - 1] + np.clip(goal[i] - out[i - 1], -step, step)
    return out


def servo_law(experiment: Path) -> tuple[dict, np.ndarray, float | None]:
    """simgap's servo law of the experiment file in MuJoCo: position actuators with kp = kt/R·V·
    duty_gain and forcerange ±kt/R·V·max_duty (the clipped duty), the back-EMF kt²/R as joint
    damping (outside the clip, as in simgap's law, and integrated implicitly by MuJoCo's Euler
    step: as actuator kv it diverges on the light wrist links at 2 ms), no friction loss or
    armature (the URDF has none). Returns the parameters, the force range and the goal rate
    limit."""
    e = json.loads(experiment.read_text())

    def per_joint(key, default=None):
        v = e.get(key, default)
        v = [float(x) for x in v.split(",")] if isinstance(v, str) else ([float(x) for x in v] if isinstance(v, list) else [float(v)])
        joints = [j.strip() for j in e["joints"].split(",")] if isinstance(e["joints"], str) else e["joints"]
        return np.array([v[joints.index(j)] if len(v) == len(joints) else v[0] for j in ARM])

    kt, r, gain, dmax = per_joint("kt"), per_joint("R"), per_joint("duty_gain"), per_joint("max_duty", 1.0)
    v = float(e["supply_voltage"])
    zero = np.zeros(len(ARM))
    params = {"kp": kt / r * v * gain, "kv": zero, "damping": kt * kt / r, "frictionloss": zero, "armature": zero}
    rate = e.get("goal_rate_limit")
    return params, kt / r * v * dmax, None if rate is None else float(rate)


def held_duty_errors(m, hold: list[Episode], experiment: Path) -> tuple[list[np.ndarray], list[float]]:
    """simgap's servo law as simgap simulates it, in MuJoCo: the duty computed from the state at
    each logged sample and held over the sample (motors with the clipped torque kt/R·V·duty as
    ctrl), the back-EMF as joint damping, the goal rate-limited from the logged goal at each
    restart. k-step errors of the held-out windows and whole-episode errors. `m` is changed."""
    import mujoco

    law, force, rate = servo_law(experiment)
    set_params(m, law)
    m.actuator_gainprm[:, 0] = 1.0
    m.actuator_biasprm[:, :3] = 0.0
    m.actuator_ctrlrange[:] = np.stack([-force, force], axis=1)
    m.actuator_forcerange[:] = np.stack([-2 * force, 2 * force], axis=1)
    d = mujoco.MjData(m)

    def run(ep, k0, q0, qd0, last, at):
        mujoco.mj_resetData(m, d)
        d.qpos[:], d.qvel[:] = q0, qd0
        sub = steps_per_sample(m, ep)
        g = ep.goal[k0].copy()
        for k in range(k0, last):
            if k > k0 and rate is not None:
                step = rate * (ep.t[k] - ep.t[k - 1])
                g = g + np.clip(ep.goal[k] - g, -step, step)
            elif k > k0:
                g = ep.goal[k]
            d.ctrl[:] = np.clip(law["kp"] * (g - d.qpos), -force, force)
            for _ in range(sub):
                mujoco.mj_step(m, d)
            at(k + 1, d.qpos)

    errors, whole = [], []
    for ep in hold:
        wins = ep.windows(MAX_WINDOWS)
        e = np.full((len(wins), len(HORIZONS), len(ARM)), np.nan)
        for w, (k0, ends) in enumerate(wins):
            def at(k1, q, w=w, ends=ends, e=e, ep=ep):
                for h, kh in enumerate(ends):
                    if kh == k1:
                        e[w, h] = capped(q - ep.q[kh])
            run(ep, k0, ep.q_hat[k0], ep.qd_hat[k0], max(x for x in ends if x is not None), at)
        errors.append(e)
        sim = np.empty_like(ep.q)
        sim[0] = ep.q[0]
        run(ep, 0, ep.q[0], (ep.q[1] - ep.q[0]) / (ep.t[1] - ep.t[0]), len(ep.t) - 1, lambda k1, q, sim=sim: sim.__setitem__(k1, q))
        whole.append(float(np.mean(capped(sim - ep.q))))
    return errors, whole


def steps_per_sample(m, ep: Episode) -> int:
    sub = round(ep.period / m.opt.timestep)
    dt = np.diff(ep.t)
    if not np.allclose(dt, sub * m.opt.timestep, rtol=1e-6, atol=1e-9):
        raise SystemExit(f"episode {ep.index}: stamps {dt.min():.6f}–{dt.max():.6f} s apart; expected {sub} MuJoCo steps of {m.opt.timestep} s each")
    return sub


def mujoco_whole(m, ep: Episode, rate_limit: float | None = None) -> float:
    """Mean |q_sim − q| over every sample and joint of the episode simulated from its first
    sample with its goals held per sample."""
    import mujoco
    from mujoco import rollout

    d = mujoco.MjData(m)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    s = np.empty(mujoco.mj_stateSize(m, spec))
    d.qpos[:] = ep.q[0]
    d.qvel[:] = (ep.q[1] - ep.q[0]) / (ep.t[1] - ep.t[0])
    mujoco.mj_getState(m, d, s, spec)
    sub = steps_per_sample(m, ep)
    ctrl = np.repeat(rate_limited(ep.goal, ep.t, rate_limit)[:-1], sub, axis=0)[None]
    state, _ = rollout.rollout(m, d, s[None], ctrl)
    q = np.vstack([ep.q[0][None], state[0, sub - 1::sub, 1:1 + m.nq]])
    return float(np.mean(capped(q - ep.q)))


# ---------------------------------------------------------------------------------------------
# (b): the optimiser


def fit_mjcf(m, fit_eps: list[Episode], budget: int, log=print) -> tuple[dict, dict]:
    """kp, kv, damping, frictionloss and armature of each arm joint (log10, bounded), fitted by
    scipy.optimize.least_squares (trf, 2-point Jacobian) on the k-step errors at every horizon
    of the fit episodes' windows (48 per episode), from the published values; stopped after
    `budget` evaluations of the residual (Jacobian columns included), keeping the best point
    seen. Returns the parameters and a record of the fit."""
    from scipy.optimize import least_squares

    published = get_params(m)
    batch = MjWindows(m, fit_eps, FIT_WINDOWS)
    lo = np.concatenate([[BOUNDS[p][0]] * len(ARM) for p in PARAMS])
    hi = np.concatenate([[BOUNDS[p][1]] * len(ARM) for p in PARAMS])

    def unpack(x):
        return {p: 10.0 ** x[i * len(ARM):(i + 1) * len(ARM)] for i, p in enumerate(PARAMS)}

    x0 = np.clip(np.concatenate([np.log10(np.maximum(published[p], 10.0 ** BOUNDS[p][0])) for p in PARAMS]), lo, hi)
    calls = {"n": 0, "best": (math.inf, x0)}

    class Budget(Exception):
        pass

    def residual(x):
        if calls["n"] >= budget:
            raise Budget
        set_params(m, unpack(x))
        e = np.concatenate([np.nan_to_num(r, nan=0.0).ravel() for r in batch.errors(m)])
        calls["n"] += 1
        cost = float(e @ e)
        if cost < calls["best"][0]:
            calls["best"] = (cost, x.copy())
        if calls["n"] % 25 == 0:
            log(f"  optimiser: {calls['n']} evaluations, best sum of squares {calls['best'][0]:.5g}")
        return e

    t0, c0 = time.time(), time.process_time()
    r0 = residual(x0)
    try:
        res = least_squares(residual, x0, bounds=(lo, hi), method="trf", diff_step=1e-3, x_scale=1.0)
        status, message = int(res.status), str(res.message)
    except Budget:
        status, message = -2, f"stopped at the budget of {budget} evaluations"
    best = calls["best"][1]
    params = unpack(best)
    set_params(m, published)
    record = {
        "method": "scipy.optimize.least_squares (trf, 2-point Jacobian, log10 parameters)",
        "bounds_log10": BOUNDS,
        "evaluations": calls["n"],
        "budget": budget,
        "status": status,
        "message": message,
        "sum_squares_start": float(r0 @ r0),
        "sum_squares_end": float(calls["best"][0]),
        "wall_s": time.time() - t0,
        "cpu_s": time.process_time() - c0,
        "fit_windows": int(batch.states.shape[0]),
        "at_bounds": [f"{p} {ARM[i % len(ARM)]}" for i, p in ((i, PARAMS[i // len(ARM)]) for i in range(len(best))) if best[i] <= lo[i] + 1e-6 or best[i] >= hi[i] - 1e-6],
    }
    return {p: [float(v) for v in params[p]] for p in PARAMS}, record


# ---------------------------------------------------------------------------------------------
# simgap


def effect_specs(report: dict, joints: list[str]) -> list[str]:
    """The report's selected effects in `simgap predict --effect` spelling: each per-joint
    parameter as one value per model joint (the effect's value on the joints it acts on, the
    vocabulary's neutral value elsewhere: 1 for a gain, +inf for a saturation limit, 0.01 rad/s
    for a dry friction's width, 0 otherwise); an inertial error per changed link."""
    neutral = {("torque_gain", "k"): 1.0, ("torque_saturation", "limit"): float("inf"), ("cogging", "periods_per_rev"): 1.0}

    def num(x):
        return "inf" if x == float("inf") else repr(float(x))

    out = []
    for e in report["selected_effects"]:
        name, p = e["effect"], e.get("parameters") or {}
        if name == "inertial_error":
            for k, jn in enumerate(e["joints"]):
                out.append(
                    f"inertial_error:joint={joints.index(jn)};mass={num(p['delta_mass'][k])};"
                    f"com={','.join(num(x) for x in p['delta_com'][k])};inertia={','.join(num(x) for x in p['delta_inertia'][k])}"
                )
            continue
        if not e.get("joints"):
            parts = [f"{k}={','.join(num(x) for x in v) if isinstance(v, list) else num(v)}" for k, v in p.items()]
            out.append(name + (":" + ";".join(parts) if parts else ""))
            continue
        parts = []
        for k, v in p.items():
            full = [0.01 if k in ("w", "vs") else neutral.get((name, k), 0.0)] * len(joints)
            for jn, x in zip(e["joints"], v):
                full[joints.index(jn)] = x if x is not None else full[joints.index(jn)]
            parts.append(f"{k}={','.join(num(x) for x in full)}")
        out.append(f"{name}:{';'.join(parts)}")
    return out


def simgap_predict(binary: str, urdf: Path, data: Path, episodes: list[int], experiment: Path, effects: list[str], out_json: Path, log=print) -> tuple[dict, float, float]:
    """`simgap predict` on the episodes (one process, RAYON_NUM_THREADS=1). Returns its JSON,
    the wall time and the child's CPU time."""
    cmd = [binary, "predict", "--urdf", str(urdf), "--log", f"{data / 'lerobot'}#{','.join(map(str, episodes))}", "--experiment", str(experiment)]
    cmd += ["--horizon", ",".join(map(str, HORIZONS)), "--json", str(out_json)]
    for e in effects:
        cmd += ["--effect", e]
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    t0 = time.time()
    r0 = os.times()
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, check=False)
    r1 = os.times()
    if p.returncode != 0:
        raise SystemExit(f"simgap predict failed ({p.returncode}): {' '.join(cmd)}\n{p.stdout}\n{p.stderr[-3000:]}")
    log("  " + " ".join(f"'{c}'" if (";" in c or "#" in c) else c for c in cmd))
    return json.loads(out_json.read_text()), time.time() - t0, (r1.children_user - r0.children_user) + (r1.children_system - r0.children_system)


def check_windows(episodes: list[Episode], pred: dict) -> str:
    """The windows laid here against those `simgap predict` lists: start times, restart states."""
    if len(pred["runs"]) != len(episodes):
        raise SystemExit(f"simgap predicted {len(pred['runs'])} runs; expected {len(episodes)}")
    worst_q, worst_t, n = 0.0, 0.0, 0
    for ep, run in zip(episodes, pred["runs"]):
        wins = ep.windows(MAX_WINDOWS)
        ws = run["window_starts"]
        if len(ws) != len(wins):
            raise SystemExit(f"episode {ep.index}: {len(wins)} windows here, {len(ws)} in simgap's JSON")
        for (k0, _), s in zip(wins, ws):
            worst_t = max(worst_t, abs(ep.t[k0] - s["t0"]))
            worst_q = max(worst_q, float(np.max(np.abs(ep.q_hat[k0] - s["q0"]))), float(np.max(np.abs(ep.qd_hat[k0] - s["qd0"]))))
            n += 1
    if worst_t > 1e-9 or worst_q > 1e-9:
        raise SystemExit(f"windows differ from simgap's: start times by {worst_t:.3g} s, restart states by {worst_q:.3g}")
    return f"{n} windows equal to simgap's (start times within {worst_t:.1g} s, restart states within {worst_q:.1g})"


def simgap_row(pred: dict, after: bool) -> dict:
    key = "after" if after else "before"
    pj = pred[f"per_joint_{key}"]  # [joint][horizon]
    maes = [r["whole_run_mae"][1 if after else 0] if r.get("whole_run_mae") is not None else float("nan") for r in pred["runs"]]
    return {
        "kstep": list(pred[key]),
        "per_joint": pj,
        "windows": int(sum(r["windows"] for r in pred["runs"])),
        "per_run": [list(r[key]) for r in pred["runs"]],
        "whole_per_run": maes,
        "whole": float(np.mean(maes)),
    }


# ---------------------------------------------------------------------------------------------
# the table


def fmt(x) -> str:
    return "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:.4f}"


def table(rows: dict, horizons=HORIZONS) -> str:
    ih = {h: i for i, h in enumerate(horizons)}
    lines = ["| model | k-step 0.1 s | k-step 0.25 s | k-step 0.5 s | whole episode (MAE) |", "|---|---|---|---|---|"]
    for key in ROWS:
        if key in rows:
            r = rows[key]
            lines.append(f"| {LABELS[key]} | " + " | ".join(fmt(r["kstep"][ih[h]]) for h in horizons) + f" | {fmt(r.get('whole'))} |")
    lines += ["", "per joint, k-step 0.5 s (RMS over windows) [rad]:", "", "| model | " + " | ".join(ARM) + " |", "|---|" + "---|" * len(ARM)]
    for key in ROWS:
        if key in rows:
            lines.append(f"| {LABELS[key]} | " + " | ".join(fmt(rows[key]["per_joint"][j][ih[0.5]]) for j in range(len(ARM))) + " |")
    return "\n".join(lines)


def table_per_run(rows: dict, hold: list[Episode]) -> str:
    """Per held-out episode: k-step 0.5 s and whole-episode error of every row."""
    i = HORIZONS.index(0.5)
    lines = ["| model | " + " | ".join(f"#{e.index} {e.name}" for e in hold) + " |", "|---|" + "---|" * len(hold)]
    for key in ROWS:
        if key in rows and "per_run" in rows[key]:
            r = rows[key]
            lines.append(f"| {LABELS[key]} | " + " | ".join(f"{fmt(k[i])} / {fmt(w)}" for k, w in zip(r["per_run"], r["whole_per_run"])) + " |")
    return "\n".join(lines)


def parse_episodes(s: str) -> list[int]:
    out = []
    for part in s.split(","):
        part = part.strip()
        if "-" in part:
            a, b = part.split("-")
            out += list(range(int(a), int(b) + 1))
        elif part:
            out.append(int(part))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="the sage-so101 folder (default: ../shared/data/sage-so101 next to the repository)")
    ap.add_argument("--fit", type=parse_episodes, default=None, help="fit episodes (LeRobot indices, e.g. 4 or 4,17,21); needed for row b")
    ap.add_argument("--holdout", type=parse_episodes, required=True, help="held-out episodes, e.g. 14,24,31,37")
    ap.add_argument("--rows", default="a,b,c,nominal,s,z,d,e", help="rows to compute, of a,b,c,nominal,s,z,d,e (default all)")
    ap.add_argument("--max-seconds", type=float, default=None, help="use only the first S seconds of every episode (MuJoCo rows and d, e only: simgap reads whole episodes)")
    ap.add_argument("--budget", type=int, default=800, help="largest number of residual evaluations of the optimiser, Jacobian columns included (row b)")
    ap.add_argument("--params", type=Path, default=None, help="row b from these fitted parameters (a JSON this script wrote) instead of fitting")
    ap.add_argument("--simgap", default=os.environ.get("SIMGAP"), help="the simgap binary (or env SIMGAP)")
    ap.add_argument("--report", type=Path, default=None, help="simgap diagnosis report (--json of simgap diagnose); needed for row c")
    ap.add_argument("--experiment", type=Path, default=HERE / "so101.experiment.json", help="the servo experiment file simgap reads the logs with")
    ap.add_argument("--json", type=Path, default=None, help="write the table and everything behind it here")
    args = ap.parse_args(argv)
    rows_wanted = [r.strip() for r in args.rows.split(",") if r.strip()]
    if unknown := [r for r in rows_wanted if r not in ROWS]:
        ap.error(f"--rows {','.join(unknown)}: expected some of {','.join(ROWS)}")
    simgap_rows = [r for r in rows_wanted if r in ("c", "nominal")]
    if simgap_rows and not args.simgap:
        ap.error(f"rows {','.join(simgap_rows)} need the simgap binary: --simgap or env SIMGAP")
    if simgap_rows and args.max_seconds is not None:
        ap.error("--max-seconds cuts the episodes, and simgap predict reads them whole: leave out rows c and nominal")
    if "c" in rows_wanted and args.report is None:
        ap.error("row c needs --report (a simgap diagnosis JSON)")
    if "b" in rows_wanted and args.params is None and not args.fit:
        ap.error("row b needs --fit (or --params)")
    if args.fit and set(args.fit) & set(args.holdout):
        ap.error(f"episodes {sorted(set(args.fit) & set(args.holdout))} are both fit and held out")
    if not (args.data / "lerobot" / "meta" / "info.json").is_file():
        raise SystemExit(f"{args.data}: no LeRobot dataset (lerobot/meta/info.json); give --data")

    t_start, c_start = time.time(), time.process_time()
    def log(s):
        print(s, file=sys.stderr, flush=True)

    hold = read_episodes(args.data / "lerobot", args.holdout, args.max_seconds)
    fit = read_episodes(args.data / "lerobot", args.fit, args.max_seconds) if args.fit else []
    out = {
        "command": " ".join([Path(sys.argv[0]).name] + (argv if argv is not None else sys.argv[1:])),
        "data": str(args.data),
        "fit": [{"episode": e.index, "motion": e.name, "seconds": float(e.t[-1] - e.t[0])} for e in fit],
        "holdout": [{"episode": e.index, "motion": e.name, "seconds": float(e.t[-1] - e.t[0])} for e in hold],
        "horizons_s": list(HORIZONS),
        "joints": ARM,
        "figure": "k-step: sqrt(mean over windows of the sum over joints of e^2) [rad], pooled over held-out episodes; per joint: RMS over windows; whole: mean |e| over samples and joints, mean over episodes",
        "rows": {},
        "checks": [],
    }
    for e in fit + hold:
        if e.glitches:
            out["checks"].append(f"episode {e.index}: {len(e.glitches)} glitch samples repaired")
    log(f"held out: {', '.join(f'#{e.index} {e.name}' for e in hold)}" + (f"; fit: {', '.join(f'#{e.index} {e.name}' for e in fit)}" if fit else ""))
    rows = out["rows"]

    # (d), (e): no model
    wins = [e.windows(MAX_WINDOWS) for e in hold]
    if "d" in rows_wanted:
        rows["d"] = row([floor_errors(e, w) for e, w in zip(hold, wins)], [np.mean(np.abs(e.q[0] + np.outer(e.t - e.t[0], (e.q[1] - e.q[0]) / (e.t[1] - e.t[0])) - e.q)) for e in hold])
    if "e" in rows_wanted:
        rows["e"] = row([goal_errors(e, w) for e, w in zip(hold, wins)], [np.mean(np.abs(e.goal - e.q)) for e in hold])

    # (a), (b): MuJoCo
    if any(r in rows_wanted for r in ("a", "b", "s", "z")):
        m, inertials = load_mjcf(args.data / "so101_new_calib.xml")
        worst = check_inertials(m, inertials)
        out["checks"].append(f"MuJoCo's body masses, principal inertias and centres of mass match the MJCF's <inertial> elements within {worst:.2g} (relative; m for the centres)")
        if worst > 1e-6:
            raise SystemExit(f"the MJCF as MuJoCo loads it differs from its <inertial> elements by {worst:.3g}")
        published = get_params(m)
        out["published"] = {p: [float(v) for v in published[p]] for p in PARAMS}
        out["published"]["forcerange"] = [float(v) for v in m.actuator_forcerange[:, 1]]
        batch = MjWindows(m, hold, MAX_WINDOWS)
        if "a" in rows_wanted:
            rows["a"] = row(batch.errors(m), [mujoco_whole(m, e) for e in hold])
            if fit:
                fb = MjWindows(m, fit, MAX_WINDOWS)
                rows["a"]["fit_kstep"] = figures(fb.errors(m))["kstep"]
        if "b" in rows_wanted:
            if args.params is not None:
                loaded = json.loads(args.params.read_text())
                params = loaded.get("fitted", loaded)
                out["fitted_from"] = str(args.params)
            else:
                log(f"fitting kp, kv, damping, frictionloss, armature of {len(ARM)} joints on episodes {args.fit} (at most {args.budget} evaluations)")
                params, record = fit_mjcf(m, fit, args.budget, log)
                out["optimiser"] = record
                log(f"  done ({record['message']}): {record['evaluations']} evaluations, {record['cpu_s']:.0f} s CPU, sum of squares {record['sum_squares_start']:.4g} -> {record['sum_squares_end']:.4g}; at a bound: {', '.join(record['at_bounds']) or 'none'}")
            out["fitted"] = params
            set_params(m, {p: np.asarray(v) for p, v in params.items()})
            rows["b"] = row(batch.errors(m), [mujoco_whole(m, e) for e in hold])
            if fit:
                rows["b"]["fit_kstep"] = figures(MjWindows(m, fit, MAX_WINDOWS).errors(m))["kstep"]
            # what each fitted group is worth: the held-out figures with it back at the published values
            out["ablation_b"] = {}
            for p in PARAMS:
                trial = {q: np.asarray(published[q] if q == p else params[q]) for q in PARAMS}
                set_params(m, trial)
                out["ablation_b"][p] = figures(batch.errors(m))
            set_params(m, published)
        if "s" in rows_wanted:
            # the MJCF's bodies with simgap's nominal servo law: how far apart the two simulators
            # are on one model (the rate limit restarts from the logged goal at every window)
            law, force, rate = servo_law(args.experiment)
            saved = m.actuator_forcerange.copy()
            set_params(m, law)
            m.actuator_forcerange[:] = np.stack([-force, force], axis=1)
            rows["s"] = row(MjWindows(m, hold, MAX_WINDOWS, rate).errors(m), [mujoco_whole(m, e, rate) for e in hold])
            out["servo_law_as_mujoco"] = {p: [float(x) for x in law[p]] for p in PARAMS} | {"forcerange": [float(x) for x in force], "goal_rate_limit": rate}
            set_params(m, published)
            m.actuator_forcerange[:] = saved
        if "z" in rows_wanted:
            errors, whole = held_duty_errors(load_mjcf(args.data / "so101_new_calib.xml")[0], hold, args.experiment)
            rows["z"] = row(errors, whole)

    # (c), nominal: simgap predict
    if simgap_rows:
        urdf = args.data / "so101_new_calib.urdf"
        with tempfile.TemporaryDirectory() as tmp:
            tmp = Path(tmp)
            pred, wall, cpu = simgap_predict(args.simgap, urdf, args.data, args.holdout, args.experiment, [], tmp / "nominal.json", log)
            out["checks"].append(check_windows(hold, pred))
            ours = figures([floor_errors(e, w) for e, w in zip(hold, wins)])["kstep"]
            diff = max(abs(a - b) for a, b in zip(ours, pred["floor"]))
            if diff > 1e-9:
                raise SystemExit(f"constant velocity here {ours}, simgap's floor {pred['floor']}: the windows or measured positions differ")
            out["checks"].append(f"constant velocity here equals simgap's floor within {diff:.1g} rad")
            out["simgap_nominal_time"] = {"wall_s": wall, "cpu_s": cpu}
            if "nominal" in rows_wanted:
                rows["nominal"] = simgap_row(pred, after=False)
            if "c" in rows_wanted:
                report = json.loads(args.report.read_text())
                specs = effect_specs(report, ARM)
                if report.get("joints") and list(report["joints"]) != ARM:
                    raise SystemExit(f"{args.report}: model joints {report['joints']}; expected {ARM}")
                exp = args.experiment
                servo = report.get("servo") or {}
                if servo.get("source") == "fitted":
                    # the corrected model simulates with the diagnosis's fitted constants
                    e = json.loads(args.experiment.read_text())
                    e["kt"] = ",".join(map(repr, servo["kt"]))
                    e["R"] = ",".join(map(repr, servo["R"]))
                    exp = tmp / "fitted.experiment.json"
                    exp.write_text(json.dumps(e))
                out["report"] = {
                    "path": str(args.report),
                    "fit_logs": report.get("fit_logs"),
                    "holdout_logs": report.get("holdout_logs"),
                    "selected_effects": [e.get("description", e["effect"]) for e in report["selected_effects"]],
                    "servo": servo,
                    "effect_specs": specs,
                }
                fit_logs = [str(x) for x in report.get("fit_logs") or []]
                if args.fit and fit_logs:
                    said = sorted({int(i) for f in fit_logs if "#" in f for i in parse_episodes(f.split("#")[-1])})
                    if said != sorted(args.fit):
                        out["checks"].append(f"WARNING: the report was fitted on episodes {said}, row b on {sorted(args.fit)}")
                # `simgap predict` parses --effect against the URDF's six joints before it locks
                # the gripper: five values per joint are refused and six give a plant that cannot
                # be built (every window counts the cap, √5·π = 7.02 rad). The corrected model is
                # therefore predicted on the URDF with the gripper joint fixed at 0, which is the
                # locked model (Model::with_joints_locked merges the jaw the way a fixed joint
                # does); its nominal figures must equal the locked URDF's.
                fixed_urdf = tmp / "so101_gripper_fixed.urdf"
                text = urdf.read_text()
                if text.count('<joint name="gripper" type="revolute">') != 1:
                    raise SystemExit(f"{urdf}: no single revolute joint 'gripper' to fix")
                fixed_urdf.write_text(text.replace('<joint name="gripper" type="revolute">', '<joint name="gripper" type="fixed">'))
                pred_c, wall, cpu = simgap_predict(args.simgap, fixed_urdf, args.data, args.holdout, exp, specs, tmp / "corrected.json", log)
                out["simgap_corrected_time"] = {"wall_s": wall, "cpu_s": cpu}
                d = max(abs(a - b) / max(abs(b), 1e-12) for a, b in zip(pred_c["before"] + [r["whole_run_mae"][0] for r in pred_c["runs"]], pred["before"] + [r["whole_run_mae"][0] for r in pred["runs"]]))
                if d > 1e-9:
                    raise SystemExit(f"the URDF with the gripper fixed predicts {pred_c['before']} without effects, the locked URDF {pred['before']}")
                out["checks"].append(f"row c runs on the URDF with the gripper joint fixed (simgap predict cannot take --effect on a model with a locked joint); without effects it predicts as the locked URDF within {d:.1g} (relative)")
                rows["c"] = simgap_row(pred_c, after=True)
                # what each selected effect is worth: the held-out figures without it
                out["ablation_c"] = {}
                for i, spec in enumerate(specs):
                    rest = specs[:i] + specs[i + 1:]
                    pr, _, _ = simgap_predict(args.simgap, fixed_urdf, args.data, args.holdout, exp, rest, tmp / f"without{i}.json", log)
                    out["ablation_c"][spec.split(":")[0] + (f" #{i}" if sum(x.split(":")[0] == spec.split(":")[0] for x in specs) > 1 else "")] = simgap_row(pr, after=True)
                held = [str(x) for x in report.get("holdout_logs") or []]
                rk = (report.get("gap") or {}).get("kstep") or {}
                if held and rk.get("after") and sorted({int(i) for f in held if "#" in f for i in parse_episodes(f.split("#")[-1])}) == sorted(args.holdout):
                    d = max(abs(a - b) for a, b in zip(rk["after"], pred_c["after"]))
                    out["checks"].append(f"row c against the report's own held-out figure (same episodes): differs by {d:.2g} rad")

    out["wall_s"] = time.time() - t_start
    out["cpu_s_python"] = time.process_time() - c_start
    text = table(rows)
    print(f"held-out episodes: {', '.join(f'{e.index} ({e.name})' for e in hold)}" + (f"; first {args.max_seconds:g} s of each" if args.max_seconds else ""))
    if fit:
        print(f"fit episodes: {', '.join(f'{e.index} ({e.name})' for e in fit)}")
    print(f"windows: {next(iter(rows.values()))['windows'] if rows else 0} held-out; figures in rad")
    print()
    print(text)
    print()
    print("per held-out episode, k-step 0.5 s / whole-episode MAE [rad]:")
    print()
    print(table_per_run(rows, hold))
    if "fitted" in out:
        print()
        pub = out.get("published")
        print("(b) fitted parameters per joint" + (" (published: " + ", ".join(f"{p} {pub[p][0]:.4g}" for p in PARAMS) + ", every joint)" if pub else "") + ":")
        print()
        print("| joint | " + " | ".join(PARAMS) + " |")
        print("|---|" + "---|" * len(PARAMS))
        for j, name in enumerate(ARM):
            print(f"| {name} | " + " | ".join(f"{out['fitted'][p][j]:.4g}" for p in PARAMS) + " |")
    for key, what, label in (("ablation_b", "(b) with one fitted group back at the published values", "reverted"), ("ablation_c", "(c) without one selected effect", "dropped")):
        if out.get(key):
            ref = rows[key[-1]]
            print()
            print(f"{what}: held-out k-step 0.5 s, pooled and per joint [rad] (first line: {LABELS[key[-1]]} as fitted):")
            print()
            print(f"| {label} | pooled | " + " | ".join(ARM) + " |")
            print("|---|---|" + "---|" * len(ARM))
            for name, r in [("nothing", ref)] + list(out[key].items()):
                print(f"| {name} | {fmt(r['kstep'][HORIZONS.index(0.5)])} | " + " | ".join(fmt(r["per_joint"][j][HORIZONS.index(0.5)]) for j in range(len(ARM))) + " |")
    if any("fit_kstep" in r for r in rows.values()):
        print()
        print("on the fit episodes (all windows), k-step 0.1 / 0.25 / 0.5 s: " + "; ".join(f"{k} " + " / ".join(fmt(x) for x in r["fit_kstep"]) for k, r in rows.items() if "fit_kstep" in r))
    print()
    for c in out["checks"]:
        print(f"check: {c}")
    print(f"time: {out['wall_s']:.0f} s wall, {out['cpu_s_python']:.0f} s CPU in Python" + (f" (optimiser {out['optimiser']['cpu_s']:.0f} s CPU, {out['optimiser']['evaluations']} evaluations)" if "optimiser" in out else ""))
    if args.json:
        out["table"] = text
        args.json.write_text(json.dumps(out, indent=1, default=float) + "\n")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
