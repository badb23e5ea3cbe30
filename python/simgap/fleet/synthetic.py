"""A synthetic fleet of the paper's arm, written as a folder of logs ``ROBOT/DATE/NAME.mcap``.

Every robot carries the friction reported for this arm (viscous 2.288 and 0.175 N·m·s/rad,
Coulomb 7.17 and 1.734 N·m), each robot scaled by its own factor (the spread between units of
one model). Two robots differ: one whose elbow Coulomb friction rises by ``rise_per_day`` each
day (a wearing gearbox), one that carries a payload at the tip of the forearm from
``payload_from_day`` on (a tool left mounted). The diagnosis never sees these effects, only the
logs. Used by the fleet tests and by ``python -m simgap.fleet.example``.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import simgap

__all__ = ["SyntheticFleet", "make_synthetic_fleet", "PAPER_ARM_URDF_TEXT"]

KP = (64.72, 32.36)
KV = (48.54, 6.472)
VISCOUS = (2.288, 0.175)
COULOMB = (7.17, 1.734)
# the effects the fleets plant, as the vocabulary names them (simgap.effect_vocabulary())
VISCOUS_EFFECT = "viscous_friction"
COULOMB_EFFECT = "coulomb_friction"

# The paper's arm as a URDF (identical to simgap.Model.paper_arm()): workers load the model
# from a file, so the synthetic fleet writes this beside its logs.
PAPER_ARM_URDF_TEXT = """<?xml version="1.0"?>
<robot name="paper_arm">
  <link name="base_link"/>
  <joint name="shoulder" type="revolute">
    <parent link="base_link"/><child link="upper_arm"/>
    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-3.14159265358979" upper="3.14159265358979" effort="200" velocity="10"/>
  </joint>
  <link name="upper_arm">
    <inertial><origin xyz="0 0 -0.091" rpy="0 0 0"/><mass value="23.902"/>
      <inertia ixx="1.266" ixy="0" ixz="0" iyy="1.266" iyz="0" izz="0.05"/></inertial>
  </link>
  <joint name="elbow" type="revolute">
    <parent link="upper_arm"/><child link="forearm"/>
    <origin xyz="0 0 -0.45" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-3.14159265358979" upper="3.14159265358979" effort="15" velocity="10"/>
  </joint>
  <link name="forearm">
    <inertial><origin xyz="0 0 -0.048" rpy="0 0 0"/><mass value="3.88"/>
      <inertia ixx="0.093" ixy="0" ixz="0" iyy="0.093" iyz="0" izz="0.01"/></inertial>
  </link>
</robot>
"""


@dataclass
class SyntheticFleet:
    """What :func:`make_synthetic_fleet` wrote: the folder, the URDF and the ground truth."""

    root: Path
    urdf: Path
    robots: list[str]
    days: list[str]
    rising: str
    payload: str
    payload_from: str
    truth: dict[tuple[str, str], list[str]] = field(default_factory=dict)
    """The hidden effects of each (robot, day), in the ``simulate`` spelling."""


def _sine_reference(joints: list[str], duration: float, rng: np.random.Generator, name: str) -> simgap.Run:
    """A smooth excitation from rest at q = 0: per joint a sum of two sinusoids."""
    t = np.arange(0.0, duration + 1e-9, 0.0025)
    q = np.zeros((t.size, 2))
    qd = np.zeros((t.size, 2))
    for j, amp in enumerate((0.7, 0.9)):
        for k in range(2):
            w = 2 * np.pi * rng.uniform(0.3, 0.6) * (k + 1)
            a = amp * rng.uniform(0.6, 1.0) / (k + 1)
            q[:, j] += a * (1 - np.cos(w * t))
            qd[:, j] += a * w * np.sin(w * t)
    return simgap.Run(joints, t, q, qd, q_ref=q, qd_ref=qd, source=name)


def make_synthetic_fleet(
    root: str | Path,
    *,
    robots: int = 6,
    days: int = 5,
    spread: float = 0.03,
    rise_per_day: float = 0.10,
    payload_mass: float = 1.5,
    payload_from_day: int = 3,
    duration: float = 2.5,
    seed: int = 0,
    first_day: _dt.date = _dt.date(2026, 3, 2),
    with_step: bool = False,
) -> SyntheticFleet:
    """Writes ``robots`` × ``days`` folders ``arm-NN/YYYY-MM-DD/`` of MCAP logs (``b-sine``, an
    excitation, fitted; ``c-sine``, another, held out as the last by name; with ``with_step``
    also ``a-step``, the paper's kind of step, fitted) and the URDF ``paper_arm.urdf`` in
    ``root``.

    ``arm-01`` is the rising robot (elbow Coulomb × (1 + ``rise_per_day`` · (day − 1))),
    ``arm-02`` carries ``payload_mass`` [kg] at the forearm's tip from day ``payload_from_day``
    (1-based). Every robot's friction is the published one times a factor drawn from
    N(1, ``spread``), fixed for that robot. Each run lasts ``duration`` seconds; seeded. Raises
    ValueError for fewer than two robots or a payload day outside the days.
    """
    if robots < 2 or not 1 <= payload_from_day <= days:
        raise ValueError(f"robots = {robots}, payload_from_day = {payload_from_day}, days = {days}: expected at least 2 robots (one rising, one with the payload) and a payload day from 1 to {days}")
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    urdf = root / "paper_arm.urdf"
    urdf.write_text(PAPER_ARM_URDF_TEXT)
    model = simgap.Model.from_urdf(urdf)
    joints = model.joint_names
    rng = np.random.default_rng(seed)
    names = [f"arm-{i + 1:02d}" for i in range(robots)]
    dates = [(first_day + _dt.timedelta(days=d)).isoformat() for d in range(days)]
    fleet = SyntheticFleet(root, urdf, names, dates, rising=names[0], payload=names[1], payload_from=dates[payload_from_day - 1])
    for robot in names:
        factor_b = 1 + spread * rng.standard_normal(2)
        factor_c = 1 + spread * rng.standard_normal(2)
        for d, date in enumerate(dates):
            b = np.asarray(VISCOUS) * factor_b
            fc = np.asarray(COULOMB) * factor_c
            if robot == fleet.rising:
                fc[1] *= 1 + rise_per_day * d
            effects = [f"{VISCOUS_EFFECT}:b={b[0]:.6g},{b[1]:.6g}", f"{COULOMB_EFFECT}:fc={fc[0]:.6g},{fc[1]:.6g}"]
            if robot == fleet.payload and d + 1 >= payload_from_day:
                effects.append(f"payload:mass={payload_mass:g};com=0,0,-0.45")
            fleet.truth[(robot, date)] = effects
            folder = root / robot / date
            folder.mkdir(parents=True, exist_ok=True)
            step_target = [rng.uniform(0.5, 1.0), rng.uniform(1.0, 1.8)]
            runs = {
                "b-sine": simgap.simulate(model, _sine_reference(joints, duration, rng, "b-sine"), controller="pd_gravity", kp=KP, kv=KV, effects=effects),
                "c-sine": simgap.simulate(model, _sine_reference(joints, duration, rng, "c-sine"), controller="pd_gravity", kp=KP, kv=KV, effects=effects),
            }
            if with_step:
                runs["a-step"] = simgap.simulate(model, step_target, controller="pd", kp=KP, kv=KV, effects=effects, duration=duration)
            for name, run in runs.items():
                simgap.write_log(run, folder / f"{name}.mcap")
    return fleet


# --- a second fleet: another robot, other effects, other formats -----------------------------

# A planar three-joint arm in the vertical plane (q = 0 hanging down), unlike the paper's arm in
# every link; its drives are of one size, so a weak elbow drive is told from a heavier forearm.
ARM3_URDF_TEXT = """<?xml version="1.0"?>
<robot name="arm3">
  <link name="base_link"/>
  <joint name="shoulder" type="revolute">
    <parent link="base_link"/><child link="link1"/>
    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-3.14159265358979" upper="3.14159265358979" effort="80" velocity="10"/>
  </joint>
  <link name="link1">
    <inertial><origin xyz="0 0 -0.15" rpy="0 0 0"/><mass value="4.0"/>
      <inertia ixx="0.04" ixy="0" ixz="0" iyy="0.04" iyz="0" izz="0.01"/></inertial>
  </link>
  <joint name="elbow" type="revolute">
    <parent link="link1"/><child link="link2"/>
    <origin xyz="0 0 -0.35" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-3.14159265358979" upper="3.14159265358979" effort="40" velocity="10"/>
  </joint>
  <link name="link2">
    <inertial><origin xyz="0 0 -0.12" rpy="0 0 0"/><mass value="2.5"/>
      <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.005"/></inertial>
  </link>
  <joint name="wrist" type="revolute">
    <parent link="link2"/><child link="link3"/>
    <origin xyz="0 0 -0.3" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-3.14159265358979" upper="3.14159265358979" effort="15" velocity="10"/>
  </joint>
  <link name="link3">
    <inertial><origin xyz="0 0 -0.08" rpy="0 0 0"/><mass value="1.0"/>
      <inertia ixx="0.005" ixy="0" ixz="0" iyy="0.005" iyz="0" izz="0.001"/></inertial>
  </link>
</robot>
"""
# PD gains for a closed loop of about 8, 12 and 23 rad/s, damped near critically, at 500 Hz
ARM3_KP = (80.0, 30.0, 6.0)
ARM3_KV = (20.0, 5.0, 0.6)
ARM3_VISCOUS = (0.8, 0.4, 0.03)
ARM3_COULOMB = (1.5, 0.9, 0.1)
ARM3_AMPLITUDE = (0.6, 0.8, 0.9)


@dataclass
class Planted:
    """One planted change: ``robot``, ``kind`` (``"drift"``, ``"step"``, ``"effect"``), the
    ``effect``, ``joint`` ('' for whole-robot) and ``parameter`` it shows in, and ``since`` (the
    first day it is there)."""

    robot: str
    kind: str
    effect: str
    joint: str
    parameter: str
    since: str


@dataclass
class ChangeFleet:
    """What :func:`make_change_fleet` wrote: the folder, the URDF, the robots, days, planted
    changes, each robot's log format, and the true parameters of each robot-day
    (``(robot, day) -> {(effect, joint, parameter): value}``, for interval coverage)."""

    root: Path
    urdf: Path
    robots: list[str]
    days: list[str]
    planted: list[Planted]
    formats: dict[str, str]
    truth: dict[tuple[str, str], dict[tuple[str, str, str], float]] = field(default_factory=dict)

    @property
    def clean(self) -> list[str]:
        """The robots with nothing planted."""
        changed = {p.robot for p in self.planted}
        return [r for r in self.robots if r not in changed]


def _multisine(joints: list[str], amplitude: tuple[float, ...], duration: float, period: float, rng: np.random.Generator, name: str) -> simgap.Run:
    """A smooth excitation from rest at q = 0, new every call: per joint three sinusoids of random
    frequencies (0.25–1.2 Hz) and phases, faded in over the first 0.3 s."""
    t = np.arange(0.0, duration + 1e-9, period)
    n = len(joints)
    q = np.zeros((t.size, n))
    qd = np.zeros((t.size, n))
    ramp = np.clip(t / 0.3, 0, 1) ** 2 * (3 - 2 * np.clip(t / 0.3, 0, 1))
    dramp = np.where(t < 0.3, 6 * (t / 0.3) * (1 - t / 0.3) / 0.3, 0.0)
    for j in range(n):
        for k in range(3):
            w = 2 * np.pi * rng.uniform(0.25, 1.2)
            a = amplitude[j] * rng.uniform(0.5, 1.0) / (k + 1.5)
            phi = rng.uniform(0, 2 * np.pi)
            s, c = np.sin(w * t + phi), np.cos(w * t + phi)
            q[:, j] += a * (s - np.sin(phi)) * ramp
            qd[:, j] += a * (w * c * ramp + (s - np.sin(phi)) * dramp)
    return simgap.Run(joints, t, q, qd, q_ref=q, qd_ref=qd, source=name)


def _write_bag(run: simgap.Run, folder: Path) -> None:
    """A rosbag2 bag folder: ``metadata.yaml`` listing one MCAP file."""
    folder.mkdir(parents=True, exist_ok=True)
    simgap.write_log(run, folder / f"{folder.name}_0.mcap")
    (folder / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: mcap\n"
        f"  relative_file_paths:\n    - {folder.name}_0.mcap\n"
    )


def make_change_fleet(
    root: str | Path,
    *,
    clean: int = 2,
    days: int = 5,
    spread: float = 0.03,
    viscous_rise: float = 0.08,
    coulomb_step: float = 1.6,
    step_day: int = 4,
    payload_mass: float = 1.0,
    payload_day: int = 3,
    weak_gain: float = 0.9,
    weak_day: int = 2,
    duration: float = 3.0,
    sample_period: float = 0.002,
    counts_per_rev: float = 2.0**19,
    seed: int = 7,
    first_day: _dt.date = _dt.date(2026, 5, 11),
) -> ChangeFleet:
    """Writes a fleet of the three-joint arm (:data:`ARM3_URDF_TEXT`, written as ``arm3.urdf``)
    with four planted changes and ``clean`` robots, ``days`` days of two logs each (``a-fit``,
    ``b-held``: a new multisine reference every log), sampled at ``sample_period`` with
    ``counts_per_rev`` encoders, under PD control with gravity compensation:

    - ``u1``: shoulder viscous friction rising ``viscous_rise`` a day (compounded) from day 1,
    - ``u2``: elbow Coulomb friction × ``coulomb_step`` from day ``step_day``,
    - ``u3``: a ``payload_mass`` payload at the wrist link's tip from day ``payload_day``,
    - ``u4``: the elbow drive delivering ``weak_gain`` of its torque from day ``weak_day``,
    - ``u5``…: clean.

    Every robot carries viscous and Coulomb friction on every joint (:data:`ARM3_VISCOUS`,
    :data:`ARM3_COULOMB`, each robot scaled by its own factor drawn from N(1, ``spread``)).
    Formats differ by robot: ``u2`` logs gzipped CSV with experiment sidecars, ``u3`` rosbag2
    bag folders, the others MCAP. Days are 1-based. Seeded. Raises ValueError for a change day
    outside the days (the step needs two days after it) or a negative number of clean robots."""
    for name, day in (("step_day", step_day), ("payload_day", payload_day), ("weak_day", weak_day)):
        if not 1 <= day <= days - (1 if name == "step_day" else 0):
            raise ValueError(f"{name} = {day}: expected 1 to {days - (1 if name == 'step_day' else 0)} for {days} days")
    if clean < 0:
        raise ValueError(f"clean = {clean}: expected 0 or more clean robots")
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    urdf = root / "arm3.urdf"
    urdf.write_text(ARM3_URDF_TEXT)
    model = simgap.Model.from_urdf(urdf)
    joints = model.joint_names
    rng = np.random.default_rng(seed)
    names = [f"u{i + 1}" for i in range(4 + clean)]
    dates = [(first_day + _dt.timedelta(days=d)).isoformat() for d in range(days)]
    planted = [
        Planted("u1", "drift", VISCOUS_EFFECT, "shoulder", "b", dates[0]),
        Planted("u2", "step", COULOMB_EFFECT, "elbow", "fc", dates[step_day - 1]),
        Planted("u3", "effect", "payload", "", "mass", dates[payload_day - 1]),
        Planted("u4", "effect", "torque_gain", "elbow", "k", dates[weak_day - 1]),
    ]
    formats = {r: "mcap" for r in names} | {"u2": "csv.gz", "u3": "bag"}
    fleet = ChangeFleet(root, urdf, names, dates, planted, formats)
    for robot in names:
        b0 = np.asarray(ARM3_VISCOUS) * (1 + spread * rng.standard_normal(3))
        fc0 = np.asarray(ARM3_COULOMB) * (1 + spread * rng.standard_normal(3))
        for d, date in enumerate(dates):
            b, fc = b0.copy(), fc0.copy()
            truth: dict[tuple[str, str, str], float] = {}
            if robot == "u1":
                b[0] *= (1 + viscous_rise) ** d
            if robot == "u2" and d + 1 >= step_day:
                fc[1] *= coulomb_step
            effects = [f"{VISCOUS_EFFECT}:b={','.join(f'{x:.6g}' for x in b)}", f"{COULOMB_EFFECT}:fc={','.join(f'{x:.6g}' for x in fc)}"]
            for j, joint in enumerate(joints):
                truth[(VISCOUS_EFFECT, joint, "b")] = float(b[j])
                truth[(COULOMB_EFFECT, joint, "fc")] = float(fc[j])
            if robot == "u3" and d + 1 >= payload_day:
                effects.append(f"payload:mass={payload_mass:g};com=0,0,-0.2")
                truth[("payload", "", "mass")] = payload_mass
            if robot == "u4" and d + 1 >= weak_day:
                effects.append(f"torque_gain:k=1,{weak_gain:g},1")
                truth[("torque_gain", "elbow", "k")] = weak_gain
            fleet.truth[(robot, date)] = truth
            folder = root / robot / date
            folder.mkdir(parents=True, exist_ok=True)
            for name in ("a-fit", "b-held"):
                reference = _multisine(joints, ARM3_AMPLITUDE, duration, sample_period, rng, name)
                run = simgap.simulate(model, reference, controller="pd_gravity", kp=ARM3_KP, kv=ARM3_KV, effects=effects, counts_per_rev=counts_per_rev, sample_period=sample_period)
                fmt = formats[robot]
                if fmt == "bag":
                    _write_bag(run, folder / name)
                else:
                    simgap.write_log(run, folder / f"{name}.{fmt}")
    return fleet
