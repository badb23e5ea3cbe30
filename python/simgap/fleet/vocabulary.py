"""The effects' parameters as the fleet tests read them: unit, neutral value, smallest change
worth a finding, and whether a reported number is a parameter at all.

The names, units by joint type and neutral values come from the one list of effects,
:func:`simgap.effect_vocabulary` (Rust's ``EffectKind``); this module adds only the fleet's
policy, the smallest change worth a finding per quantity. Everything else in
:mod:`simgap.fleet` asks these four functions of ``(effect, param[, joint_type])``:

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

import math
from typing import Any, Literal

__all__ = ["JOINT_TYPES", "is_parameter", "min_change", "neutral", "unit"]

JointType = Literal["revolute", "prismatic", ""]
JOINT_TYPES = ("revolute", "prismatic")

# the smallest change worth a finding, per quantity of the Rust vocabulary, in its SI unit
# (fleet policy: the vocabulary itself has names, units and neutral values)
_MIN_CHANGE: dict[str, float] = {
    "damping": 1e-3,
    "effort": 1e-2,
    "velocity": 1e-3,
    "joint_inertia": 1e-5,
    "stiffness": 1e-2,
    "position": 1e-3,
    "mass": 5e-3,
    "length": 1e-3,
    "link_inertia": 1e-5,
    "time": 1e-4,
    "ratio": 5e-3,
}
# quantities that are reported but are no physical parameter to test
_NOT_PARAMETER = {"count", "width"}


def _vocabulary() -> dict[tuple[str, str], dict[str, Any]]:
    """(effect, param) -> the parameter's entry of :func:`simgap.effect_vocabulary`."""
    from simgap import effect_vocabulary

    return {(e["name"], p["name"]): p for e in effect_vocabulary() for p in e["parameters"]}


_PARAMS = _vocabulary()


def _base(param: str) -> str:
    return param.split("[", 1)[0]


def _entry(effect: str, param: str) -> tuple[str, float | None] | None:
    """(quantity, neutral value) of a parameter; a neutral value that is not finite (no
    saturation: an infinite limit) is no value to judge against."""
    p = _PARAMS.get((effect, _base(param)))
    if p is None:
        return None
    n = p["neutral"]
    return (str(p["quantity"]), float(n) if n is not None and math.isfinite(n) else None)


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
    p = _PARAMS[(effect, _base(param))]
    return str(p["unit"]["prismatic" if joint_type == "prismatic" else "revolute"])


def min_change(effect: str, param: str, joint_type: str = "revolute") -> float:
    """The smallest difference [in :func:`unit`] the fleet reports for this parameter: the floor
    under the fleet's spread and under an effect's distance from its neutral value; 0 for an
    unknown parameter."""
    e = _entry(effect, param)
    if e is None or e[0] in _NOT_PARAMETER:
        return 0.0
    return _MIN_CHANGE.get(e[0], 0.0)


def is_parameter(effect: str, param: str) -> bool:
    """False for numbers a report gives that are not a physical parameter to test: counts
    (``identifiable_directions``, ``periods_per_rev``) and simulation settings (``w``)."""
    e = _entry(effect, param)
    return e is None or e[0] not in _NOT_PARAMETER
