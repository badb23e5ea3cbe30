#!/usr/bin/env python3
"""BAM's XL330 pendulum simulator, written from its equations (our implementation, not BAM's code).

Rhoban's BAM ("Better Actuator Models", github.com/Rhoban/bam, Apache-2.0; M. Duclusaud,
G. Passault et al., ICRA 2025) models a position-controlled servo as firmware P loop → DC
motor with back-EMF → a friction "budget" → a semi-implicit Euler step. This module
re-implements that model for the XL330 pendulum bench so that simgap's comparison baselines do
not depend on BAM's package. Where a detail matters, the BAM file it was read from is named;
``tests/python/test_bam_servo_data.py`` checks the result against BAM's PyPI package
(``better-actuator-models``) when it is importable.

The model, per step of length dt from the state (q, q̇) (``bam/simulate.py``, ``Simulator.step``
and ``rollout_log``; ``bam/actuator.py``, ``VoltageControlledActuator``):

* duty = clip(kp · e_g · (goal − q), −1, 1), with the firmware ``kp`` register of the log and
  the error gain e_g [duty/(rad·kp)]. The control uses q **without** ``q_offset``.
* volts = vin · duty. BAM's ``DCMotorActuator.load_log`` takes ``vin`` from the log's metadata,
  i.e. the **nominal** 7.4 V, not the logged ``input_volts``; we do the same (``vin_mode =
  "nominal"``); ``vin_mode = "logged"`` uses the logged voltage per sample instead (our
  variant, not BAM's).
* τ_m = en · (kt/R · volts − kt²/R · q̇): back-EMF; τ_m = 0 with torque off (en = 0).
* gravity (``bam/testbench.py``, ``Pendulum``): τ_e = −(m + m_arm/2) · g · l · sin(q + q_offset),
  g = 9.80665; the ``q_offset`` is a bench offset applied to gravity (and passed to the
  torque, which ignores q), never to the control error or to the logged position.
* inertia I = m l² + m_arm l²/3 + armature (m_arm = 0 here: the logs carry none).
* friction budget (``bam/model.py``, ``Model.compute_frictions``): a static part τ_fl that
  grows with the gearbox torque for M3–M6 and with a Stribeck factor s = exp(−|q̇/q̇_s|^α) for
  M2, M4–M6, and a viscous coefficient b: see :func:`friction_budget`.
* the friction applied is the torque that would stop the joint within dt, clipped to the
  budget: τ_stop = I/dt · q̇ + τ_m + τ_e, τ_f = −sign(τ_stop) · min(|τ_stop|, τ_fl + b|q̇|).
  So a joint at rest stays at rest while the driving torque is below the budget (stick).
* q̈ = (τ_m + τ_e + τ_f)/I; q̇ ← clip(q̇ + q̈ dt, ±100); q ← q + q̇ dt + ½ q̈ dt² (with the
  *updated* q̇, as BAM writes it).

Error gain per parameter file. BAM's current XL330 gain is (4096/2π)/(256·885) ≈ 0.0028774
(``bam/dynamixel/actuator.py``; ``d73e7c4`` "fixing error gain"). The published files
(``params/published``, BAM's ``bam/params/xl330`` fitted in June 2026) and ``xl330-branch/m1``
(``af22604``) were fitted with it. ``xl330-branch/m2`` and ``m6`` (``16837b3``) were fitted when
the code used 0.00246. :func:`error_gain_for` encodes this.

Current limit. BAM's PyPI release 1.0.2 gives the XL330 a firmware current limit of 1.75 A
(``max_current``), added after the published files were fitted (``2e3a0e4``, July 2026) and
removed again on ``main`` (``edef2f4``, "Max current is not limited in voltage mode"). We
follow the model the files were fitted with: no current limit.
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bam_to_simgap import XL330_ERROR_GAIN, load_raw  # noqa: E402

G = 9.80665
#: the XL330 error gain BAM's code used before d73e7c4 (2026-02-03).
OLD_XL330_ERROR_GAIN = 0.00246

#: BAM's six friction structures (``bam/model.py``, ``models``).
STRUCTURES = {
    "m1": dict(load_dependent=False, directional=False, stribeck=False, quadratic=False),
    "m2": dict(load_dependent=False, directional=False, stribeck=True, quadratic=False),
    "m3": dict(load_dependent=True, directional=False, stribeck=False, quadratic=False),
    "m4": dict(load_dependent=True, directional=False, stribeck=True, quadratic=False),
    "m5": dict(load_dependent=True, directional=True, stribeck=True, quadratic=False),
    "m6": dict(load_dependent=True, directional=True, stribeck=True, quadratic=True),
}


@dataclass
class BamParams:
    """One BAM parameter file: its friction structure, values and the error gain it goes with."""

    model: str
    values: dict
    error_gain: float
    source: str = ""
    flags: dict = field(default_factory=dict)

    @property
    def label(self) -> str:
        return self.source or self.model

    def v(self, name: str) -> float:
        return float(self.values.get(name, 0.0))


def error_gain_for(path: Path, model: str) -> float:
    """The XL330 error gain a BAM parameter file was fitted with (see the module docstring)."""
    path = Path(path)
    if path.parent.name == "xl330-branch" and model in ("m2", "m6"):
        return OLD_XL330_ERROR_GAIN
    return XL330_ERROR_GAIN


def load_params(path: Path, error_gain: float | None = None) -> BamParams:
    """A BAM params JSON (``kt``, ``R``, ``armature``, ``q_offset``, friction terms, ``model``)."""
    path = Path(path)
    with open(path) as f:
        data = json.load(f)
    model = data["model"]
    if model not in STRUCTURES:
        raise ValueError(f"{path}: unknown BAM model {model!r}")
    if data.get("actuator", "xl330") != "xl330":
        raise ValueError(f"{path}: actuator {data.get('actuator')!r}, this simulator is the XL330's")
    gain = error_gain if error_gain is not None else error_gain_for(path, model)
    return BamParams(model=model, values=data, error_gain=gain, source=f"{path.parent.name}/{path.stem}", flags=STRUCTURES[model])


def param_files(data: Path) -> list[Path]:
    """Every BAM parameter file of the data folder: published m1–m6, then the xl330 branch's."""
    data = Path(data)
    return sorted((data / "params" / "published").glob("m*.json")) + sorted((data / "params" / "xl330-branch").glob("m*.json"))


@dataclass
class Bench:
    """The pendulum: tip mass [kg], axis-to-mass length [m], arm mass [kg], firmware kp, vin [V]."""

    mass: float
    length: float
    arm_mass: float
    kp: float
    vin: float

    @classmethod
    def from_meta(cls, meta: dict) -> "Bench":
        return cls(float(meta["mass"]), float(meta["length"]), float(meta.get("arm_mass", 0.0)), float(meta["kp"]), float(meta["vin"]))

    def inertia(self) -> float:
        return self.mass * self.length**2 + self.arm_mass / 3.0 * self.length**2

    def gravity(self, q):
        return -(self.mass + self.arm_mass / 2.0) * G * self.length * np.sin(q)


def friction_budget(p: BamParams, tau_m, tau_e, dq):
    """BAM's friction budget: the static part τ_fl [N·m] and the viscous coefficient b.

    With G = |τ_e − τ_m| (M3, M4) or G = |k_e τ_e − k_m τ_m| (directional M5, M6; k_e, k_m the
    ``load_friction_external`` / ``_motor`` values, and G_s the same with the ``_stribeck``
    coefficients) and s = exp(−|q̇/q̇_s|^α):

    τ_fl = f_base + [M3/M4: μ G | M5/M6: G] + s·f_stribeck + [M4: μ_s G s | M5/M6: G_s s]
           + [M6: s · (|τ_e| < |τ_m|) c_e τ_e² + s · (|τ_e| > |τ_m|) c_m τ_m², when sign τ_e ≠ sign τ_m]

    (c_e = ``load_friction_external_quad``, c_m = ``load_friction_motor_quad``, paired as in
    ``bam/model.py``).
    """
    f = p.flags
    v = p.v
    fl = np.full(np.shape(dq), v("friction_base"), dtype=float)
    if f["directional"]:
        gear = np.abs(tau_e * v("load_friction_external") - tau_m * v("load_friction_motor"))
        if f["stribeck"]:
            gear_s = np.abs(tau_e * v("load_friction_external_stribeck") - tau_m * v("load_friction_motor_stribeck"))
    else:
        gear = np.abs(tau_e - tau_m)
    if f["load_dependent"]:
        fl = fl + (gear if f["directional"] else v("load_friction_base") * gear)
    if f["stribeck"]:
        s = np.exp(-(np.abs(dq / v("dtheta_stribeck")) ** v("alpha")))
        fl = fl + s * v("friction_stribeck")
        if f["load_dependent"]:
            fl = fl + (gear_s * s if f["directional"] else v("load_friction_stribeck") * gear * s)
            if f["quadratic"]:
                opposite = np.sign(tau_e) != np.sign(tau_m)
                motor_side = np.abs(tau_e) < np.abs(tau_m)
                external_side = np.abs(tau_e) > np.abs(tau_m)
                fl = fl + s * (motor_side * v("load_friction_external_quad") * tau_e**2 + external_side * v("load_friction_motor_quad") * tau_m**2) * opposite
    return fl, v("friction_viscous")


def step(p: BamParams, bench: Bench, q, dq, goal, en, dt, vin=None):
    """One BAM step for arrays of states (windows in parallel). Returns the new (q, q̇).

    ``goal``, ``en`` (0/1), ``dt`` and ``vin`` broadcast against ``q``; ``vin`` None = nominal.
    """
    kt, R = p.v("kt"), p.v("R")
    q_off = p.v("q_offset")
    vin = bench.vin if vin is None else vin
    duty = np.clip((goal - q) * bench.kp * p.error_gain, -1.0, 1.0)
    volts = vin * duty
    tau_m = (kt * volts / R - kt * kt * dq / R) * en
    tau_e = bench.gravity(q + q_off)
    fl, b = friction_budget(p, tau_m, tau_e, dq)
    inertia = bench.inertia() + p.v("armature")
    net = tau_m + tau_e
    tau_stop = inertia / dt * dq + net
    net = net - np.sign(tau_stop) * np.minimum(np.abs(tau_stop), fl + b * np.abs(dq))
    acc = net / inertia
    dq = np.clip(dq + acc * dt, -100.0, 100.0)
    q = q + dq * dt + 0.5 * acc * dt * dt
    return q, dq


def rollout(p: BamParams, bench: Bench, q0: float, dq0: float, goal, en, dt, vin=None) -> np.ndarray:
    """Simulated positions at every sample of a log, from (q0, q̇0) at sample 0, control simulated.

    ``goal``, ``en`` per sample (n), ``dt`` a scalar or per sample (the step after each sample),
    ``vin`` None (nominal) or per sample. positions[i] is the state at sample i (BAM's
    ``rollout_log(simulate_control=True)`` records before stepping).
    """
    goal = np.asarray(goal, float)
    en = np.asarray(en, float)
    n = len(goal)
    dts = np.broadcast_to(np.asarray(dt, float), (n,))
    vins = None if vin is None else np.broadcast_to(np.asarray(vin, float), (n,))
    q, dq = np.array([float(q0)]), np.array([float(dq0)])
    out = np.empty(n)
    for i in range(n):
        out[i] = q[0]
        q, dq = step(p, bench, q, dq, goal[i], en[i], dts[i], None if vins is None else vins[i])
    return out


def resample(raw: dict, dt: float = 0.005) -> dict:
    """BAM's ``bam/process.py`` resample of a raw log: linear interpolation onto 0, dt, 2dt, …

    (stamps as recorded, the grid starts at 0 s and stops before the last stamp; the first
    point is extrapolated from the first two samples; ``torque_enable`` thresholded at 0.5).
    Returns arrays ``t``, ``q``, ``qd``, ``goal``, ``torque_enable``, ``voltage`` and ``dt``.
    """
    t = np.asarray(raw["t"], float)
    ts = np.arange(0.0, t[-1], dt)
    # the segment BAM uses for each grid time: the first frame with t <= t_{frame+1}
    frame = np.clip(np.searchsorted(t, ts, side="left") - 1, 0, len(t) - 2)
    t1, t2 = t[frame], t[frame + 1]
    w = (ts - t1) / (t2 - t1)

    def interp(x):
        x = np.asarray(x, float)
        return x[frame] + (x[frame + 1] - x[frame]) * w

    return {
        "t": ts,
        "q": interp(raw["q"]),
        "qd": interp(raw["qd"]),
        "goal": interp(raw["goal"]),
        "torque_enable": (interp(raw["torque_enable"]) > 0.5).astype(float),
        "voltage": interp(raw["voltage"]),
        "dt": dt,
    }


def bam_mae(p: BamParams, raw: dict, vin_mode: str = "nominal") -> float:
    """BAM's own measure (``bam/mae.py``): the whole-run mean absolute position error of a
    rollout from the first sample with simulated control, on BAM's 5 ms resample of the log
    (``mae.py`` evaluates a folder of ``process.py`` outputs), every resampled sample counted
    (torque on and off)."""
    r = resample(raw)
    bench = Bench.from_meta(raw["meta"])
    sim = rollout(p, bench, r["q"][0], r["qd"][0], r["goal"], r["torque_enable"], r["dt"], r["voltage"] if vin_mode == "logged" else None)
    return float(np.mean(np.abs(sim - r["q"])))


def raw_mae(p: BamParams, raw: dict, vin_mode: str = "nominal") -> float:
    """The same rollout on the raw, non-uniform timeline (each step the gap to the next stamp)."""
    t = np.asarray(raw["t"], float)
    dts = np.append(np.diff(t), np.median(np.diff(t)))
    bench = Bench.from_meta(raw["meta"])
    sim = rollout(p, bench, raw["q"][0], raw["qd"][0], raw["goal"], raw["torque_enable"], dts, raw["voltage"] if vin_mode == "logged" else None)
    return float(np.mean(np.abs(sim - np.asarray(raw["q"]))))


def kstep(p: BamParams, raw: dict, windows: list, horizons, vin_mode: str = "nominal") -> dict:
    """k-step prediction from given start states on the raw timeline.

    ``windows``: list of (t0, q0, q̇0), t0 on the log's time axis starting at 0 (the CSV's
    ``time``). Each window starts at the first sample with time ≥ t0 − 1 µs, steps sample by
    sample (the goal and torque enable of each sample held until the next stamp) and is
    compared with the log at t0 + h (both linearly interpolated between stamps). A window is
    used for horizon h when t0 + h is within the log. Returns per horizon the list of errors
    (sim − log) and, on the same windows, the constant-velocity errors q0 + q̇0 h − q_log.
    """
    t = np.asarray(raw["t"], float) - raw["t"][0]
    qlog = np.asarray(raw["q"], float)
    goal = np.asarray(raw["goal"], float)
    en = np.asarray(raw["torque_enable"], float)
    volt = np.asarray(raw["voltage"], float)
    bench = Bench.from_meta(raw["meta"])
    horizons = [float(h) for h in horizons]
    hmax = max(horizons)
    W = len(windows)
    out = {h: {"model": [], "floor": []} for h in horizons}
    if W == 0:
        return out
    t0 = np.array([w[0] for w in windows], float)
    q0 = np.array([w[1] for w in windows], float)
    qd0 = np.array([w[2] for w in windows], float)
    i0 = np.searchsorted(t, t0 - 1e-6, side="left")
    # steps needed to pass t0 + hmax (or the end of the log)
    iend = np.minimum(np.searchsorted(t, t0 + hmax, side="left"), len(t) - 1)
    nsteps = int(np.max(iend - i0)) + 1 if W else 0
    last = len(t) - 1
    times = np.empty((W, nsteps + 1))
    qs = np.empty((W, nsteps + 1))
    q, dq = q0.copy(), qd0.copy()
    # start time of each window is t0 itself (its first stamp is at or just after t0)
    idx = np.minimum(i0, last)
    times[:, 0] = t0
    qs[:, 0] = q
    cur_t = t0.copy()
    for k in range(nsteps):
        nxt = np.minimum(idx + 1, last)
        dt = t[nxt] - cur_t
        active = dt > 0
        dts = np.where(active, dt, 1.0)
        qn, dqn = step(p, bench, q, dq, goal[idx], en[idx], dts, volt[idx] if vin_mode == "logged" else None)
        q = np.where(active, qn, q)
        dq = np.where(active, dqn, dq)
        cur_t = np.where(active, t[nxt], cur_t + 1e-9)
        times[:, k + 1] = cur_t
        qs[:, k + 1] = q
        idx = nxt
    for h in horizons:
        for w in range(W):
            te = t0[w] + h
            if te > t[-1] + 1e-9:
                continue
            qsim = float(np.interp(te, times[w], qs[w]))
            qref = float(np.interp(te, t, qlog))
            out[h]["model"].append(qsim - qref)
            out[h]["floor"].append(q0[w] + qd0[w] * h - qref)
    return out


def load(path: Path) -> dict:
    """A raw BAM log (see :func:`bam_to_simgap.load_raw`)."""
    return load_raw(path)


if __name__ == "__main__":
    import argparse

    from bam_to_simgap import default_data_dir, raw_logs

    ap = argparse.ArgumentParser(description="BAM's whole-run MAE (its own measure) of every BAM parameter file on every raw log")
    ap.add_argument("--data", type=Path, default=default_data_dir())
    args = ap.parse_args()
    files = param_files(args.data)
    params = [load_params(f) for f in files]
    logs = [load_raw(f) for f in raw_logs(args.data)]
    print("log".ljust(22) + "".join(p.label.rjust(20) for p in params))
    for log in logs:
        print(log["name"].ljust(22) + "".join(f"{1000 * bam_mae(p, log):20.2f}" for p in params))
