"""Figures of a diagnosis on matplotlib (``pip install "simgap[plot]"``).

Every helper takes a :class:`simgap.Report` and returns the matplotlib ``Figure`` it drew on (or
draws on the ``ax`` given). Times are seconds since each log's start; position errors are on a
log axis, where a corrected simulation's success shows even when it lies on the measured curve.

- :func:`trajectories`: one held-out run, every joint: measured, nominal and corrected position
  above, ``|q_meas − q_sim|`` below.
- :func:`error_panel`: the ``|q_meas − q_sim|`` panel of one joint alone.
- :func:`residual_vs_velocity`: the nominal torque residual against q̇ on the fit runs (friction
  shows as a step at q̇ = 0 and a slope).
- :func:`candidates`: each candidate's held-out L² after / before on a log axis, with
  "not simulated", "diverged" and "worse" drawn apart.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from simgap._simgap import Report, Run

__all__ = ["candidates", "error_panel", "residual_vs_velocity", "trajectories"]

MEASURED = {"color": "0.45", "linewidth": 3.0, "label": "measured"}
NOMINAL = {"color": "tab:red", "linewidth": 1.0, "label": "nominal model"}
CORRECTED = {"color": "tab:blue", "linewidth": 1.5, "linestyle": "--", "label": "with selected effects"}


def _pyplot() -> Any:
    try:
        import matplotlib.pyplot as plt
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError('simgap.plot needs matplotlib: pip install "simgap[plot]"') from e
    return plt


def _joint_index(report: Report, joint: int | str) -> int:
    if isinstance(joint, str):
        try:
            return report.joints.index(joint)
        except ValueError:
            raise ValueError(f"joint {joint!r} is not a joint of the model; expected one of {report.joints}") from None
    if not 0 <= joint < len(report.joints):
        raise ValueError(f"joint {joint} is out of range; expected 0 ≤ joint < {len(report.joints)}")
    return joint


def _run_index(report: Report, run: int) -> int:
    n = len(report["holdout_logs"])
    if not 0 <= run < n:
        raise ValueError(f"run {run} is out of range; expected 0 ≤ run < {n} (the held-out runs)")
    return run


def _units(report: Report, j: int) -> tuple[str, str, str]:
    """Position, velocity and effort units of joint ``j`` by its type (m, m/s, N on a
    prismatic joint; rad, rad/s, N·m otherwise)."""
    types = report["joint_types"] if "joint_types" in report else []
    if j < len(types) and types[j] == "prismatic":
        return "m", "m/s", "N"
    return "rad", "rad/s", "N·m"


def _error(sim: Run | None, measured: Run, j: int) -> tuple[np.ndarray, np.ndarray] | None:
    if sim is None:
        return None
    n = min(len(sim.t), len(measured.t))
    err = np.abs(sim.q[:n, j] - measured.q[:n, j])
    return measured.t[:n] - measured.t[0], np.maximum(err, 1e-12)


def error_panel(report: Report, run: int = 0, joint: int | str = 0, ax: Axes | None = None) -> Figure:
    """``|q_measured − q_simulated|`` of one joint of held-out run ``run`` on a log axis, for the
    nominal model and with the selected effects."""
    plt = _pyplot()
    i, j = _run_index(report, run), _joint_index(report, joint)
    if ax is None:
        _, ax = plt.subplots(figsize=(9, 2.8), layout="constrained")
    measured = report.holdout[i]
    selected = bool(report.selected_effects)
    for sim, style in ((report.holdout_nominal[i], NOMINAL), (report.holdout_corrected[i] if selected else None, CORRECTED)):
        e = _error(sim, measured, j)
        if e is not None:
            ax.semilogy(*e, color=style["color"], linewidth=1.0, label=style["label"])
    ax.set_xlabel("time since the log's start [s]")
    ax.set_ylabel(f"|q_meas − q_sim| [{_units(report, j)[0]}]")
    ax.grid(True, which="major", alpha=0.3)
    return ax.figure


def trajectories(report: Report, run: int = 0, joints: list[int | str] | None = None) -> Figure:
    """Held-out run ``run`` (index into ``report.holdout``): for each joint, the measured,
    nominal and corrected position above and the error panel below; the legend sits outside
    the plots."""
    plt = _pyplot()
    i = _run_index(report, run)
    js = [_joint_index(report, j) for j in (joints if joints is not None else range(len(report.joints)))]
    fig, axes = plt.subplots(2 * len(js), 1, figsize=(10, 3.6 * len(js)), sharex=True, layout="constrained", squeeze=False, height_ratios=[3, 2] * len(js))
    measured = report.holdout[i]
    t0 = measured.t[0]
    nominal = report.holdout_nominal[i]
    corrected = report.holdout_corrected[i] if report.selected_effects else None
    for k, j in enumerate(js):
        top, bottom = axes[2 * k, 0], axes[2 * k + 1, 0]
        top.plot(measured.t - t0, measured.q[:, j], **MEASURED)
        for sim, style in ((nominal, NOMINAL), (corrected, CORRECTED)):
            if sim is not None:
                top.plot(sim.t - sim.t[0], sim.q[:, j], **style)
        top.set_ylabel(f"{report.joints[j]}: q [{_units(report, j)[0]}]")
        top.grid(True, alpha=0.3)
        error_panel(report, i, j, ax=bottom)
    axes[0, 0].set_title(f"held-out run {report['holdout_logs'][i]}")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right upper")
    return fig


def residual_vs_velocity(report: Report, joint: int | str = 0, ax: Axes | None = None) -> Figure:
    """The nominal torque residual τ_cmd − (H q̈ + C q̇ + g) of one joint against its velocity,
    over every fit run: viscous friction is a slope, Coulomb friction a step at q̇ = 0."""
    plt = _pyplot()
    j = _joint_index(report, joint)
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 3.5), layout="constrained")
    for f in report.fit_residuals:
        ax.scatter(f["qd"][:, j], f["residual"][:, j], s=2, alpha=0.4, label=f["log"])
    _, velocity, effort = _units(report, j)
    ax.set_xlabel(f"{report.joints[j]}: q̇ [{velocity}]")
    ax.set_ylabel(f"torque residual [{effort}]")
    ax.grid(True, alpha=0.3)
    return ax.figure


def _outcome(c: dict[str, Any]) -> str:
    l2, ratio = c.get("holdout_l2_after"), c.get("holdout_ratio")
    # the JSON has null for non-finite numbers: a null L² with a reason is "not simulated"
    if l2 is None and "not simulated" in (c.get("reason") or ""):
        return "not simulated"
    if l2 is None or ratio is None or not math.isfinite(ratio):
        return "diverged"
    if c.get("selected"):
        return "selected"
    return "worse" if ratio > 1.0 else "better"


COLORS = {"selected": "tab:green", "better": "tab:blue", "worse": "tab:orange", "diverged": "tab:red", "not simulated": "0.6"}


def candidates(report: Report, ax: Axes | None = None) -> Figure:
    """Each candidate's held-out L² after / before on a log axis, as a bar from 1 (no change):
    left is better, right is worse; "diverged" runs to the edge in red outline, and "not
    simulated" (a fit that is not physical) is a grey outline claiming no length."""
    plt = _pyplot()
    cands = report.candidates
    if ax is None:
        _, ax = plt.subplots(figsize=(9, 0.4 * len(cands) + 1.2), layout="constrained")
    ratios = [c["holdout_ratio"] for c in cands if isinstance(c.get("holdout_ratio"), (int, float)) and c["holdout_ratio"] > 0]
    lo, hi = min([1.0, *ratios]) / 1.6, max([1.0, *ratios]) * 1.6
    seen: set[str] = set()
    for k, c in enumerate(cands):
        y = len(cands) - 1 - k
        outcome = _outcome(c)
        color = COLORS[outcome]
        label = outcome if outcome not in seen else None
        seen.add(outcome)
        if outcome == "diverged":
            ax.barh(y, hi - 1.0, left=1.0, height=0.6, fill=False, edgecolor=color, linewidth=2, label=label)
        elif outcome == "not simulated":
            ax.barh(y, 1.25 - 0.8, left=0.8, height=0.6, fill=False, edgecolor=color, hatch="//", label=label)
        else:
            r = min(max(c["holdout_ratio"], lo), hi)
            ax.barh(y, abs(r - 1.0), left=min(r, 1.0), height=0.6, color=color, alpha=0.8, label=label)
    ax.set_xscale("log")
    ax.set_xlim(lo, hi)
    ax.axvline(1.0, color="black", linewidth=1)
    ax.set_yticks(range(len(cands)), [c["effect"] for c in reversed(cands)])
    ax.set_xlabel("held-out L² after / before (each candidate alone; 1 = no change)")
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    ax.grid(True, axis="x", which="major", alpha=0.3)
    return ax.figure
