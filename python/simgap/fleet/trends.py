"""What changes and what stands out: per robot, a trend test and a change-point test over the
days; per day, each robot against the fleet or against the effect's neutral value.

Both read the fleet table (:data:`simgap.fleet.TABLE_COLUMNS`). A *series* is one
``(effect, joint, parameter)``. Only **identified parameters** are tested: rows whose
``uncertainty`` (the report's 95 % half-width, so ``σ = uncertainty / 1.96``) is finite and
positive, and whose parameter is a physical parameter (:func:`vocabulary.is_parameter`: not a
count such as ``identifiable_directions``, not a setting such as the smoothing width ``w``). A
coordinate the data do not resolve (a planar arm's out-of-plane centre of mass) is reported
without an interval and is never tested.

**Changes over the days** (:func:`drift`), per robot and series, over the days on which the
diagnosis selected that effect (at least ``min_days``). Three models of the series are fitted
by weighted least squares: a constant, a line ``a + slope · day`` and a single step (a level
before day ``k``, another from day ``k`` on, at least two days on each side, ``k`` the best
split). The reported intervals are used *as they are*: their scale is calibrated on the fleet.
The interval scale ``c²`` of a series is the median, over the robots with that series, of the
reduced χ² of each robot's line (corrected for the median of a χ² distribution), so the robots
that do not change set it and intervals that are 3× too wide make every σ 3× smaller, not only
larger ones 3× larger; with fewer than ``min_robots_pool`` robots, the robot's own reduced χ².
A robot that scatters more than the fleet about its own best model has its σ inflated further
(``√max(1, χ²ᵣ/c²)``), never shrunk below the fleet's.

- the **trend** test: ``z = slope / se``, flagged when ``|z| ≥ z_drift`` and the change is
  large enough to act on: ``|slope|`` at least ``min_rate_per_day`` of the line's value on the
  first day, and ``|slope| · span`` at least the parameter's :func:`vocabulary.min_change`;
- the **step** test: ``z = (after − before) / se``, flagged when ``|z| ≥ z_drift`` and the step
  is at least ``min_step`` of the level before (10 %) and :func:`vocabulary.min_change`;
- when both are flagged, the one with the smaller BIC (``χ² + p ln n``, p = 2 for the line, 3
  for the step) names the change: "rising 8 %/day since day 1" or "since day 4, a step of ×1.6".

**Against the fleet or against neutral** (:func:`outliers`), per day and series, across the
robots diagnosed that day:

- where the effect was selected for **at least half** of the robots (friction, which every
  unit has): the robust z ``(x − median) / √(spread² + σ²)``, ``spread = max(1.4826·MAD,
  rel_floor·|median|, min_change)``: the fleet's median absolute deviation (which one odd robot
  does not inflate), floored at ``rel_floor`` (5 %) of the median because units of one model
  legitimately differ by a few per cent, and at the unit-aware minimum; needs ``min_robots``
  robots with a value;
- where it was selected for **fewer than half** (a torque gain, an offset, a payload: an effect
  present on one robot only): the robot is judged against the effect's
  :func:`vocabulary.neutral` value with its own uncertainty, ``z = (x − neutral) / σ``, and must
  be at least ``min_change`` away from it; the spread floor, made for unit-to-unit variation,
  does not apply. The other robots are not scored (they sit at the neutral value). Parameters
  without a neutral value (a payload's centre of mass) are not judged this way.

A robot is flagged that day when ``|z| ≥ z_outlier`` (default 4), unless the same series
changes over the days for that robot (reported once, as the change).
"""

from __future__ import annotations

import datetime as _dt
import math
from typing import Any

import numpy as np
import pandas as pd

from . import vocabulary

__all__ = ["KEY", "Z95", "day_numbers", "drift", "outliers", "series_table"]

Z95 = 1.959963984540054
KEY = ["effect", "joint", "parameter"]

DRIFT_COLUMNS = [
    "robot", *KEY, "unit", "days", "first_day", "last_day", "slope_per_day", "slope_se", "z", "baseline", "rate_per_day", "chi2_red", "scale",
    "step_day", "step_before", "step_after", "step_ratio", "step_z", "bic_const", "bic_trend", "bic_step", "change", "drifting",
]  # fmt: skip
OUTLIER_COLUMNS = ["day", "robot", *KEY, "unit", "value", "sigma", "present", "reference", "median", "spread", "scale", "z", "drifting", "outlier"]


def day_numbers(days: pd.Series) -> pd.Series:
    """Days as numbers for a trend: days since the first one where every day parses as an
    ISO date (``YYYY-MM-DD``), else the rank of the day's name (0, 1, 2, …)."""
    unique = sorted(set(days))
    try:
        dates = {d: _dt.date.fromisoformat(str(d)[:10]) for d in unique}
        first = min(dates.values())
        mapping = {d: float((v - first).days) for d, v in dates.items()}
    except ValueError:
        mapping = {d: float(i) for i, d in enumerate(unique)}
    return days.map(mapping).astype(float)


def series_table(table: pd.DataFrame) -> pd.DataFrame:
    """The rows of the fleet table that are tested: successful, an identified physical
    parameter (finite positive uncertainty, not a count or setting), with ``sigma`` (the
    standard deviation, uncertainty / 1.96), ``t`` (the day as a number) and ``min_change``
    (:func:`vocabulary.min_change`)."""
    ok = table[(table["status"] == "ok") & table["effect"].notna() & table["parameter"].notna()].copy()
    ok["joint"] = ok["joint"].fillna("")
    if "joint_type" not in ok.columns:
        ok["joint_type"] = ""
    ok["joint_type"] = ok["joint_type"].fillna("").astype(str)
    unc = pd.to_numeric(ok["uncertainty"], errors="coerce")
    value = pd.to_numeric(ok["value"], errors="coerce")
    physical = np.array([vocabulary.is_parameter(str(e), str(p)) for e, p in zip(ok["effect"], ok["parameter"])], dtype=bool)
    keep = physical & np.isfinite(unc.to_numpy(float)) & (unc.to_numpy(float) > 0) & np.isfinite(value.to_numpy(float))
    ok = ok[keep].copy()
    ok["value"] = value[keep].astype(float)
    ok["sigma"] = unc[keep].astype(float) / Z95
    ok["t"] = day_numbers(table["day"]).loc[ok.index] if len(ok) else pd.Series(dtype=float)
    ok["min_change"] = [vocabulary.min_change(str(e), str(p), jt) for e, p, jt in zip(ok["effect"], ok["parameter"], ok["joint_type"])]
    return ok


# --- fits of one series ----------------------------------------------------------------------


def _line(t: np.ndarray, x: np.ndarray, w: np.ndarray) -> tuple[float, float, float, float]:
    """(slope, intercept at t[0], χ², Σw(t − t̄)²) of the weighted line through (t, x)."""
    tm = np.sum(w * t) / np.sum(w)
    xm = np.sum(w * x) / np.sum(w)
    sxx = float(np.sum(w * (t - tm) ** 2))
    slope = float(np.sum(w * (t - tm) * (x - xm)) / sxx) if sxx > 0 else math.nan
    resid = x - (xm + slope * (t - tm))
    return slope, float(xm + slope * (t[0] - tm)), float(np.sum(w * resid**2)), sxx


def _step(x: np.ndarray, w: np.ndarray, min_side: int) -> tuple[int, float, float, float, float]:
    """(k, level before, level after, χ², se of the difference at unit scale) of the best single
    split: x[:k] and x[k:], each side at least ``min_side`` points; k = -1 when none fits."""
    best = (-1, math.nan, math.nan, math.inf, math.nan)
    for k in range(min_side, len(x) - min_side + 1):
        w1, w2 = w[:k], w[k:]
        m1 = float(np.sum(w1 * x[:k]) / np.sum(w1))
        m2 = float(np.sum(w2 * x[k:]) / np.sum(w2))
        chi2 = float(np.sum(w1 * (x[:k] - m1) ** 2) + np.sum(w2 * (x[k:] - m2) ** 2))
        if chi2 < best[3]:
            best = (k, m1, m2, chi2, math.sqrt(1 / np.sum(w1) + 1 / np.sum(w2)))
    return best


def _chi2_median_factor(dof: float) -> float:
    """Median of χ²_dof / dof (Wilson–Hilferty), to turn a median of reduced χ² into a scale."""
    return (1 - 2 / (9 * dof)) ** 3 if dof > 0 else 1.0


def _pooled_scale(s: pd.DataFrame, min_days: int, min_robots_pool: int) -> dict[tuple[str, str, str], float]:
    """Per series, the fleet's interval scale c² (see the module's text), where at least
    ``min_robots_pool`` robots have ``min_days`` days of it."""
    out = {}
    for key, g in s.groupby(KEY, sort=False):
        chi2s, dofs = [], []
        for _robot, r in g.groupby("robot", sort=False):
            if len(r) < max(min_days, 3):
                continue
            w = 1 / r["sigma"].to_numpy(float) ** 2
            _, _, chi2, sxx = _line(r["t"].to_numpy(float), r["value"].to_numpy(float), w)
            if sxx > 0:
                chi2s.append(chi2 / (len(r) - 2))
                dofs.append(len(r) - 2)
        if len(chi2s) >= min_robots_pool:
            c2 = float(np.median(chi2s)) / _chi2_median_factor(float(np.median(dofs)))
            if c2 > 0 and math.isfinite(c2):
                out[(str(key[0]), str(key[1]), str(key[2]))] = c2
    return out


def drift(
    table: pd.DataFrame,
    *,
    z_drift: float = 4.0,
    min_rate_per_day: float = 0.02,
    min_step: float = 0.10,
    min_days: int = 3,
    min_robots_pool: int = 3,
) -> pd.DataFrame:
    """The change tests of every robot and series (see the module's text), one row each:
    ``robot, effect, joint, parameter, unit, days, first_day, last_day``; the trend
    ``slope_per_day`` (unit per day), ``slope_se``, ``z``, ``baseline`` (the line on the first
    day), ``rate_per_day`` (slope / baseline), ``chi2_red`` (of the line, with the reported
    intervals), ``scale`` (the interval scale c used: σ × c is the σ the tests use); the best
    step ``step_day`` (its first day), ``step_before``, ``step_after``, ``step_ratio``,
    ``step_z``; ``bic_const``, ``bic_trend``, ``bic_step``; ``change`` (``"trend"``, ``"step"``
    or ``""``) and ``drifting`` (a change was found)."""
    s = series_table(table)
    pool = _pooled_scale(s, min_days, min_robots_pool)
    rows = []
    for (robot, effect, joint, parameter), g in s.groupby(["robot", *KEY], sort=True):
        g = g.sort_values("t")
        n = len(g)
        row: dict[str, Any] = {c: math.nan for c in DRIFT_COLUMNS}
        row.update({"robot": robot, "effect": effect, "joint": joint, "parameter": parameter, "unit": g["unit"].iloc[0], "days": n, "first_day": g["day"].iloc[0], "last_day": g["day"].iloc[-1], "step_day": "", "change": "", "drifting": False})
        if n >= max(min_days, 3):
            t, x = g["t"].to_numpy(float), g["value"].to_numpy(float)
            w0 = 1 / g["sigma"].to_numpy(float) ** 2
            slope, base, chi2_line0, sxx0 = _line(t, x, w0)
            chi2_red = chi2_line0 / (n - 2)
            c2 = pool.get((effect, joint, parameter), chi2_red)
            c2 = c2 if c2 > 0 and math.isfinite(c2) else 1.0
            w = w0 / c2
            chi2_line, sxx = chi2_line0 / c2, sxx0 / c2
            chi2_const = float(np.sum(w * (x - np.sum(w * x) / np.sum(w)) ** 2))
            min_change = float(g["min_change"].iloc[0])
            # trend: the slope's se at the fleet's scale, inflated where this robot scatters more
            se = math.sqrt(1 / sxx) * math.sqrt(max(1.0, chi2_line / (n - 2))) if sxx > 0 else math.nan
            z = slope / se if se > 0 else math.nan
            rate = slope / abs(base) if base else math.nan
            span = float(t[-1] - t[0])
            trend_ok = bool(abs(z) >= z_drift and abs(rate) >= min_rate_per_day and abs(slope) * span >= min_change)
            row.update({"slope_per_day": slope, "slope_se": se, "z": z, "baseline": base, "rate_per_day": rate, "chi2_red": chi2_red, "scale": math.sqrt(c2)})
            row.update({"bic_const": chi2_const + math.log(n), "bic_trend": chi2_line + 2 * math.log(n)})
            # step: the best single split, its se likewise
            step_ok = False
            k, m1, m2, chi2_step, se_unit = _step(x, w, 2)
            if k > 0:
                se_step = se_unit * math.sqrt(max(1.0, chi2_step / max(n - 2, 1)))
                z_step = (m2 - m1) / se_step
                step_ok = bool(abs(z_step) >= z_drift and abs(m2 - m1) >= max(min_step * abs(m1), min_change))
                row.update({"step_day": g["day"].iloc[k], "step_before": m1, "step_after": m2, "step_ratio": m2 / m1 if m1 else math.nan, "step_z": z_step, "bic_step": chi2_step + 3 * math.log(n)})
            if trend_ok and step_ok:
                row["change"] = "step" if row["bic_step"] < row["bic_trend"] else "trend"
            elif trend_ok or step_ok:
                row["change"] = "trend" if trend_ok else "step"
            row["drifting"] = bool(row["change"])
        rows.append(row)
    return pd.DataFrame(rows, columns=DRIFT_COLUMNS).astype({"drifting": bool})


def outliers(
    table: pd.DataFrame,
    *,
    z_outlier: float = 4.0,
    rel_floor: float = 0.05,
    min_robots: int = 4,
    drift_table: pd.DataFrame | None = None,
    **drift_kwargs: float,
) -> pd.DataFrame:
    """Every robot, day and series against the fleet or against the effect's neutral value
    (see the module's text), one row each: ``day, robot, effect, joint, parameter, unit,
    value, sigma, present, reference, median, spread, scale, z, drifting, outlier``.
    ``reference`` is ``"fleet"`` (``median`` is the fleet's median, ``spread`` its floored
    robust spread) or ``"neutral"`` (``median`` is the neutral value, ``spread`` 0).
    ``present`` is False for robots whose diagnosis did not select the effect that day, drawn
    at the neutral value and not scored (z NaN). ``scale`` is the denominator of z.
    ``drift_table`` (default: :func:`drift` of the same table with ``drift_kwargs``) marks the
    series reported as a change instead."""
    s = series_table(table)
    diagnosed = table.loc[table["status"] == "ok", ["robot", "day"]].drop_duplicates()
    if drift_table is None:
        drift_table = drift(table, **drift_kwargs)  # type: ignore[arg-type]
    drifting = {tuple(r) for r in drift_table.loc[drift_table["drifting"], ["robot", *KEY]].itertuples(index=False)}
    rows = []
    for (effect, joint, parameter), g in s.groupby(KEY, sort=True):
        neutral = vocabulary.neutral(str(effect), str(parameter))
        min_change = float(g["min_change"].iloc[0])
        unit = g["unit"].iloc[0]
        for day, robots in diagnosed.groupby("day", sort=True):
            have = g[g["day"] == day].drop_duplicates("robot").set_index("robot")
            if have.empty:
                continue
            names = list(robots["robot"])
            base = {"day": day, "effect": effect, "joint": joint, "parameter": parameter, "unit": unit}
            if neutral is not None and 2 * len(have) < len(names):
                # an effect the fleet does not have: each robot that has it against neutral
                for robot in names:
                    if robot not in have.index:
                        rows.append({**base, "robot": robot, "value": neutral, "sigma": math.nan, "present": False, "reference": "neutral", "median": neutral, "spread": 0.0, "scale": math.nan, "z": math.nan, "drifting": False, "outlier": False})
                        continue
                    v, sig = float(have.at[robot, "value"]), float(have.at[robot, "sigma"])
                    z = (v - neutral) / sig
                    d = (robot, effect, joint, parameter) in drifting
                    flagged = bool(abs(z) >= z_outlier and abs(v - neutral) >= min_change and not d)
                    rows.append({**base, "robot": robot, "value": v, "sigma": sig, "present": True, "reference": "neutral", "median": neutral, "spread": 0.0, "scale": sig, "z": z, "drifting": d, "outlier": flagged})
                continue
            if len(have) < min_robots:
                continue
            # an effect the fleet has: each robot against the fleet's median and spread
            x = have["value"].to_numpy(float)
            median = float(np.median(x))
            mad = float(np.median(np.abs(x - median)))
            spread = max(1.4826 * mad, rel_floor * abs(median), min_change)
            for robot in names:
                if robot not in have.index:
                    continue
                v, sig = float(have.at[robot, "value"]), float(have.at[robot, "sigma"])
                scale = math.sqrt(spread**2 + sig**2)
                z = (v - median) / scale
                d = (robot, effect, joint, parameter) in drifting
                rows.append({**base, "robot": robot, "value": v, "sigma": sig, "present": True, "reference": "fleet", "median": median, "spread": spread, "scale": scale, "z": z, "drifting": d, "outlier": bool(abs(z) >= z_outlier and not d)})
    return pd.DataFrame(rows, columns=OUTLIER_COLUMNS).astype({"present": bool, "drifting": bool, "outlier": bool})
