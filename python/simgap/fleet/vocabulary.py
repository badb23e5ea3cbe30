"""The effects' parameters as the fleet tests read them: unit, neutral value, smallest change
worth a finding, and whether a reported number is a parameter at all.

This is the fleet's only table of the effects vocabulary (BRIEF §3.2); everything else in
:mod:`simgap.fleet` asks these functions. It is meant to be sourced from the Rust effect
vocabulary later, so the interface is four functions of ``(effect, param[, joint_type])``:

- :func:`neutral` ``(effect, param) -> float | None``: the value of the parameter when the
  effect is absent (0 for a friction, 1 for a torque gain), None where an absent effect has no
  value (a saturation limit, a payload's centre of mass, a Stribeck velocity);
- :func:`unit` ``(effect, param, joint_type) -> str``: the unit, following the joint type
  (``"revolute"``: rad, N·m; ``"prismatic"``: m, N); whole-robot and link parameters ignore it;
- :func:`min_change` ``(effect, param, joint_type) -> float``: the smallest difference, in that
  unit, that the fleet reports (a floor under every spread and every effect size: a 9e-9 kg
  mass correction is no finding however small its interval);
- :func:`is_parameter` ``(effect, param) -> bool``: False for counts (``identifiable_directions``,
  ``periods_per_rev``) and settings (the smoothing width ``w``), which are reported but never
  tested.

``param`` may carry a component suffix (``com[2]``, ``delta_inertia[0]``): it is ignored.
Unknown effects and parameters are parameters with neutral 0, unit ``""`` and no floor, so a
new effect is tested (against 0) rather than dropped.
"""

from __future__ import annotations

from typing import Literal

__all__ = ["JOINT_TYPES", "is_parameter", "min_change", "neutral", "unit"]

JointType = Literal["revolute", "prismatic", ""]
JOINT_TYPES = ("revolute", "prismatic")

# quantity -> (revolute unit, prismatic unit, smallest change worth a finding, in that unit)
_QUANTITY: dict[str, tuple[str, str, float]] = {
    "damping": ("N·m·s/rad", "N·s/m", 1e-3),
    "torque": ("N·m", "N", 1e-2),
    "velocity": ("rad/s", "m/s", 1e-3),
    "rotor_inertia": ("kg·m²", "kg", 1e-5),
    "stiffness": ("N·m/rad", "N/m", 1e-2),
    "position": ("rad", "m", 1e-3),
    "mass": ("kg", "kg", 5e-3),
    "length": ("m", "m", 1e-3),
    "link_inertia": ("kg·m²", "kg·m²", 1e-5),
    "time": ("s", "s", 1e-4),
    "ratio": ("–", "–", 5e-3),
}
_NOT_PARAMETER = {"count": "–", "setting_velocity": ""}

# (effect, param) -> (quantity, neutral value or None)
_PARAMS: dict[tuple[str, str], tuple[str, float | None]] = {
    ("viscous_friction", "b"): ("damping", 0.0),
    ("coulomb_friction", "fc"): ("torque", 0.0),
    ("coulomb_friction", "w"): ("setting_velocity", None),
    ("stribeck_friction", "fc"): ("torque", 0.0),
    ("stribeck_friction", "fs"): ("torque", 0.0),
    ("stribeck_friction", "vs"): ("velocity", None),
    ("stribeck_friction", "w"): ("setting_velocity", None),
    ("armature", "ia"): ("rotor_inertia", 0.0),
    ("payload", "mass"): ("mass", 0.0),
    ("payload", "com"): ("length", None),
    ("inertial_error", "delta_mass"): ("mass", 0.0),
    ("inertial_error", "delta_com"): ("length", 0.0),
    ("inertial_error", "delta_inertia"): ("link_inertia", 0.0),
    ("inertial_error", "identifiable_directions"): ("count", None),
    ("torque_gain", "k"): ("ratio", 1.0),
    ("torque_offset", "offset"): ("torque", 0.0),
    ("torque_saturation", "limit"): ("torque", None),
    ("time_delay", "delay"): ("time", 0.0),
    ("cogging", "amplitude"): ("torque", 0.0),
    ("cogging", "periods_per_rev"): ("count", None),
    ("directional_friction", "fc_pos"): ("torque", 0.0),
    ("directional_friction", "fc_neg"): ("torque", 0.0),
    ("directional_friction", "b_pos"): ("damping", 0.0),
    ("directional_friction", "b_neg"): ("damping", 0.0),
    ("directional_friction", "w"): ("setting_velocity", None),
    ("load_friction", "fc"): ("torque", 0.0),
    ("load_friction", "mu"): ("ratio", 0.0),
    ("load_friction", "w"): ("setting_velocity", None),
    ("joint_spring", "k"): ("stiffness", 0.0),
    ("joint_spring", "q0"): ("position", None),
    ("back_emf", "kb"): ("damping", 0.0),
}


def _base(param: str) -> str:
    return param.split("[", 1)[0]


def _entry(effect: str, param: str) -> tuple[str, float | None] | None:
    return _PARAMS.get((effect, _base(param)))


def neutral(effect: str, param: str) -> float | None:
    """The parameter's value when ``effect`` is absent, or None where an absent effect has none."""
    e = _entry(effect, param)
    return 0.0 if e is None else e[1]


def unit(effect: str, param: str, joint_type: str = "revolute") -> str:
    """The parameter's unit for a joint of ``joint_type`` (``"revolute"`` or ``"prismatic"``;
    ``""`` or anything else reads as revolute). Raises ValueError for another joint type name."""
    if joint_type not in ("revolute", "prismatic", "continuous", ""):
        raise ValueError(f"joint type {joint_type!r}: expected 'revolute', 'prismatic' or 'continuous'")
    e = _entry(effect, param)
    if e is None:
        return ""
    if e[0] in _NOT_PARAMETER:
        if e[0] == "setting_velocity":
            return "m/s" if joint_type == "prismatic" else "rad/s"
        return _NOT_PARAMETER[e[0]]
    rev, pri, _ = _QUANTITY[e[0]]
    return pri if joint_type == "prismatic" else rev


def min_change(effect: str, param: str, joint_type: str = "revolute") -> float:
    """The smallest difference [in :func:`unit`] the fleet reports for this parameter: the floor
    under the fleet's spread and under an effect's distance from its neutral value; 0 for an
    unknown parameter."""
    e = _entry(effect, param)
    if e is None or e[0] in _NOT_PARAMETER:
        return 0.0
    return _QUANTITY[e[0]][2]


def is_parameter(effect: str, param: str) -> bool:
    """False for numbers a report gives that are not a physical parameter to test: counts
    (``identifiable_directions``, ``periods_per_rev``) and simulation settings (``w``)."""
    e = _entry(effect, param)
    return e is None or e[0] not in _NOT_PARAMETER
