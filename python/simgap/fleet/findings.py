"""The findings of a fleet, in words: which robot, which parameter, what kind of change, since
when, which test, and what else the robot-day's own report says could explain it.

:func:`find` runs the tests of :mod:`simgap.fleet.trends` with one set of thresholds and
returns the three tables every front end (the command line, the HTML report, the summary)
shows; :func:`flagged_robots` turns the two test tables into one row per finding.

Kinds of finding (``finding``):

- ``drift``: the parameter follows a line over the days ("rising 8.1 %/day since 2026-03-02"),
- ``step``: it jumps once and stays ("since 2026-03-05, a step of ×1.60"),
- ``effect``: an effect the fleet does not have (a payload, a torque gain, an offset), away
  from its neutral value by its own uncertainty ("k = 0.895 ± 0.004, neutral 1, since …"),
- ``outlier``: a parameter the fleet has, outside the fleet's band that day.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pandas as pd

from . import trends

__all__ = ["FLAG_COLUMNS", "Findings", "find", "flagged_robots"]

FLAG_COLUMNS = ["robot", "finding", "effect", "joint", "parameter", "since", "test", "detail", "alternatives"]
DRIFT_ARGS = ("z_drift", "min_rate_per_day", "min_step", "min_days", "min_robots_pool")
OUTLIER_ARGS = ("z_outlier", "rel_floor", "min_robots")
FLAG_ARGS = ("min_flagged_days",)


@dataclass
class Findings:
    """What :func:`find` returns: ``drift`` (:func:`trends.drift`), ``outliers``
    (:func:`trends.outliers`) and ``flags`` (:func:`flagged_robots`)."""

    drift: pd.DataFrame
    outliers: pd.DataFrame
    flags: pd.DataFrame


def find(table: pd.DataFrame, reports: dict[tuple[str, str], dict[str, Any]] | None = None, **thresholds: Any) -> Findings:
    """Runs the change tests and the fleet / neutral tests on ``table`` and lists the findings.

    ``thresholds``: keyword arguments of :func:`trends.drift` (``z_drift``,
    ``min_rate_per_day``, ``min_step``, ``min_days``, ``min_robots_pool``) and of
    :func:`trends.outliers` (``z_outlier``, ``rel_floor``, ``min_robots``) and
    ``min_flagged_days`` of :func:`flagged_robots`; anything else is a
    TypeError. ``reports`` (``(robot, day) -> JSON report``) supplies each finding's
    ``alternatives``."""
    unknown = sorted(set(thresholds) - set(DRIFT_ARGS) - set(OUTLIER_ARGS) - set(FLAG_ARGS))
    if unknown:
        raise TypeError(f"unknown threshold(s) {unknown}; expected some of {sorted(DRIFT_ARGS + OUTLIER_ARGS + FLAG_ARGS)}")
    dr = trends.drift(table, **{k: v for k, v in thresholds.items() if k in DRIFT_ARGS})
    ol = trends.outliers(table, drift_table=dr, **{k: v for k, v in thresholds.items() if k in OUTLIER_ARGS})
    return Findings(dr, ol, flagged_robots(dr, ol, reports, **{k: v for k, v in thresholds.items() if k in FLAG_ARGS}))


def _num(x: float, unit: str) -> str:
    return f"{x:.4g} {unit}".rstrip()


def _alternatives(robot: str, effect: str, days: list[str], reports: dict[tuple[str, str], dict[str, Any]] | None) -> str:
    """The report's ``alternatives`` on ``days`` that explain the fit without ``effect``:
    "inertial_error (3 of 4 days: why)"; "" when every report decides."""
    if not reports:
        return ""
    seen: dict[tuple[str, ...], list[str]] = {}
    why: dict[tuple[str, ...], str] = {}
    checked = 0
    for day in days:
        report = reports.get((robot, day))
        if not report:
            continue
        checked += 1
        for alt in report.get("alternatives") or []:
            names = tuple(str(e) for e in alt.get("effects") or [])
            if effect in names:
                continue
            seen.setdefault(names, []).append(day)
            why.setdefault(names, str(alt.get("why") or ""))
    parts = []
    for names, on in seen.items():
        label = " + ".join(names) if names else "no effect"
        parts.append(f"{label} ({len(on)} of {checked} days: {why[names]})" if why[names] else f"{label} ({len(on)} of {checked} days)")
    return "; ".join(parts)


def flagged_robots(drift: pd.DataFrame, outliers: pd.DataFrame, reports: dict[tuple[str, str], dict[str, Any]] | None = None, *, min_flagged_days: int = 2) -> pd.DataFrame:
    """One row per finding: ``robot, finding`` (``drift``, ``step``, ``effect``,
    ``outlier``), ``effect, joint, parameter, since`` (the first day of the change or the first
    day flagged), ``test`` (``trend``, ``step``, ``neutral``, ``fleet``: which test flagged
    it), ``detail`` (the finding in words, with its numbers) and ``alternatives`` (effect sets
    the robot-days' own reports say explain the runs as well without this effect).

    A per-day finding (``effect``, ``outlier``) needs ``min_flagged_days`` flagged days
    (default 2): one odd robot-day (a diagnosis that attributed a payload's first day partly to
    friction) stays in the outliers table and is not reported until it recurs."""
    rows = []
    for r in drift[drift["drifting"]].itertuples(index=False):
        unit = str(r.unit) if isinstance(r.unit, str) else ""
        if r.change == "step":
            since = r.step_day
            detail = (
                f"since {r.step_day}, a step of ×{r.step_ratio:.3g}: {_num(r.step_before, unit)} → {_num(r.step_after, unit)} "
                f"(z = {r.step_z:.1f}; trend z = {r.z:.1f}; interval scale ×{r.scale:.2g})"
            )
        else:
            since = r.first_day
            word = "rising" if r.slope_per_day > 0 else "falling"
            span = trends.day_numbers(pd.Series([r.first_day, r.last_day])).iloc[1]
            detail = (
                f"{word} {100 * abs(r.rate_per_day):.1f} %/day since {r.first_day}: {_num(r.baseline, unit)} → {_num(r.baseline + r.slope_per_day * span, unit)} "
                f"({r.slope_per_day:+.3g} ± {r.slope_se:.2g} per day, z = {r.z:.1f} over {r.days} days; interval scale ×{r.scale:.2g})"
            )
        days = sorted(d for (rb, d) in (reports or {}) if rb == r.robot and str(since) <= d <= str(r.last_day))
        rows.append({"robot": r.robot, "finding": "drift" if r.change == "trend" else "step", "effect": r.effect, "joint": r.joint, "parameter": r.parameter, "since": since, "test": r.change, "detail": detail, "alternatives": _alternatives(r.robot, r.effect, days, reports)})
    flagged = outliers[outliers["outlier"]]
    for (robot, effect, joint, parameter, reference), g in flagged.groupby(["robot", *trends.KEY, "reference"], sort=True):
        g = g.sort_values("day")
        days = list(g["day"])
        if len(days) < min_flagged_days:
            continue
        unit = str(g["unit"].iloc[0]) if isinstance(g["unit"].iloc[0], str) else ""
        lo, hi = g["value"].min(), g["value"].max()
        values = _num(lo, unit) if lo == hi else f"{lo:.4g} to {_num(hi, unit)}"
        if reference == "neutral":
            sig = 1.96 * g["sigma"].median()
            detail = f"{parameter} = {values} (± {sig:.2g} typical 95 %) against its neutral {g['median'].iloc[0]:g}, on {len(days)} day(s) since {days[0]}; |z| up to {g['z'].abs().max():.0f}"
            finding, test = "effect", "neutral"
        else:
            detail = f"{parameter} = {values} against a fleet median of {g['median'].median():.4g} (spread {g['spread'].median():.2g}) on {len(days)} day(s): {', '.join(days)}; |z| up to {g['z'].abs().max():.1f}"
            finding, test = "outlier", "fleet"
        rows.append({"robot": robot, "finding": finding, "effect": effect, "joint": joint, "parameter": parameter, "since": days[0], "test": test, "detail": detail, "alternatives": _alternatives(robot, effect, days, reports)})
    return pd.DataFrame(rows, columns=FLAG_COLUMNS).sort_values(["robot", "finding", "effect", "joint", "parameter"]).reset_index(drop=True)
