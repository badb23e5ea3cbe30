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
    N(1, ``spread``), fixed for that robot. Each run lasts ``duration`` seconds; seeded.
    """
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
            effects = [f"viscous_friction:b={b[0]:.6g},{b[1]:.6g}", f"coulomb_friction:fc={fc[0]:.6g},{fc[1]:.6g}"]
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
