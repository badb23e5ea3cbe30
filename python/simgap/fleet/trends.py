"""What drifts and what stands out: trend tests per robot over days, robust outlier scores
across the fleet per day.

Both read the fleet table (:data:`simgap.fleet.TABLE_COLUMNS`). A *series* is one
``(effect, joint, parameter)``; ``uncertainty`` in the table is the report's 95 % half-width,
so a value's standard deviation is taken as ``σ = uncertainty / 1.96``.

**Drift** (:func:`drift`), per robot and series, over the days on which the diagnosis selected
that effect for that robot (at least ``min_days``): a weighted least-squares line
``value = a + slope · day`` with weights ``1/σ²`` (unweighted where a σ is missing). The
slope's standard error is the weighted one, ``1/√(Σw (d − d̄)²)``, inflated by
``√(χ²/(n − 2))`` when the points scatter about the line more than their σ say (bootstrap
half-widths are often optimistic). A series **drifts** when ``|slope| / se ≥ z_drift``
(default 4) **and** the relative rate ``|slope| / |weighted mean|`` is at least
``min_rate_per_day`` (default 2 % a day): significant and large enough to act on.

**Outliers** (:func:`outliers`), per day and series, across the robots diagnosed that day.
Where the effect was selected for fewer than half of those robots, the others count at its
neutral value (0 for frictions, payload mass, offsets…; 1 for a torque gain): the fleet's
normal is not to have it, and a robot that has it stands out. Where most robots have it, a
robot without it gets no score that day (one selection that did not happen says little about
the value). The robust z of robot ``i`` is ``(x_i − median) / s_i`` with
``s_i = √(spread² + σ_i²)`` and ``spread = max(1.4826·MAD, rel_floor·|median|)``: the fleet's
spread (the median absolute deviation, floored at ``rel_floor`` = 5 % of the median because
units of one model legitimately differ by a few per cent), combined with the robot's own
uncertainty. A robot is an **outlier** that day when ``|z| ≥ z_outlier`` (default 4: with the
floor, at least 20 % away from the median) and the series is not one that :func:`drift` flags
for that robot (a drifting parameter leaves the fleet band by drifting; it is reported once,
as drift). Days need at least ``min_robots`` (default 4) robots with a value.
"""

from __future__ import annotations

import datetime as _dt
import math

import numpy as np
import pandas as pd

__all__ = ["NEUTRAL", "day_numbers", "drift", "outliers", "series_table"]

Z95 = 1.959963984540054
NEUTRAL: dict[tuple[str, str], float] = {("torque_gain", "k"): 1.0}
"""Values of parameters of an effect that is absent; 0 for every parameter not listed here,
and no value (not filled) for parameters in :data:`NO_NEUTRAL`."""
NO_NEUTRAL = {("torque_saturation", "limit"), ("stribeck_friction", "vs"), ("cogging", "periods_per_rev"), ("payload", "com")}

KEY = ["effect", "joint", "parameter"]


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
    """The successful rows of the fleet table that carry a parameter, with ``sigma`` (the
    standard deviation, uncertainty / 1.96) and ``t`` (the day as a number)."""
    ok = table[(table["status"] == "ok") & table["effect"].notna() & table["parameter"].notna()].copy()
    ok["joint"] = ok["joint"].fillna("")
    ok["sigma"] = ok["uncertainty"] / Z95
    ok["t"] = day_numbers(table["day"]).loc[ok.index] if len(ok) else pd.Series(dtype=float)
    return ok


def _wls(t: np.ndarray, x: np.ndarray, sigma: np.ndarray) -> tuple[float, float, float, float]:
    """(slope, standard error, weighted mean, reduced χ²) of the weighted line through (t, x)."""
    n = len(t)
    weighted = bool(np.all(np.isfinite(sigma)) and np.all(sigma > 0))
    w = 1.0 / sigma**2 if weighted else np.ones(n)
    tm = np.sum(w * t) / np.sum(w)
    xm = np.sum(w * x) / np.sum(w)
    sxx = np.sum(w * (t - tm) ** 2)
    if sxx <= 0:
        return math.nan, math.nan, xm, math.nan
    slope = np.sum(w * (t - tm) * (x - xm)) / sxx
    resid = x - (xm + slope * (t - tm))
    chi2 = float(np.sum(w * resid**2) / (n - 2)) if n > 2 else math.nan
    if weighted:
        se = math.sqrt(1.0 / sxx) * math.sqrt(max(1.0, chi2 if math.isfinite(chi2) else 1.0))
    else:
        se = math.sqrt(chi2 / sxx) if math.isfinite(chi2) else math.nan
    return float(slope), float(se), float(xm), chi2


def drift(table: pd.DataFrame, *, z_drift: float = 4.0, min_rate_per_day: float = 0.02, min_days: int = 3) -> pd.DataFrame:
    """The trend test of every robot and series (see the module's text), one row each:
    ``robot, effect, joint, parameter, days, first_day, last_day, slope_per_day, slope_se,
    z, mean, rate_per_day, chi2_red, drifting``. ``slope_per_day`` is in the parameter's unit
    per day; ``rate_per_day`` relative to the mean."""
    s = series_table(table)
    rows = []
    for (robot, effect, joint, parameter), g in s.groupby(["robot", *KEY], sort=True):
        g = g.sort_values("t")
        row = {"robot": robot, "effect": effect, "joint": joint, "parameter": parameter, "days": len(g), "first_day": g["day"].iloc[0], "last_day": g["day"].iloc[-1]}
        slope = se = mean = chi2 = math.nan
        if len(g) >= max(min_days, 3):
            slope, se, mean, chi2 = _wls(g["t"].to_numpy(float), g["value"].to_numpy(float), g["sigma"].to_numpy(float))
        z = slope / se if se and math.isfinite(se) and se > 0 else math.nan
        rate = slope / abs(mean) if mean and math.isfinite(mean) else math.nan
        flagged = bool(math.isfinite(z) and abs(z) >= z_drift and math.isfinite(rate) and abs(rate) >= min_rate_per_day)
        rows.append({**row, "slope_per_day": slope, "slope_se": se, "z": z, "mean": mean, "rate_per_day": rate, "chi2_red": chi2, "drifting": flagged})
    cols = ["robot", *KEY, "days", "first_day", "last_day", "slope_per_day", "slope_se", "z", "mean", "rate_per_day", "chi2_red", "drifting"]
    return pd.DataFrame(rows, columns=cols).astype({"drifting": bool})


def _neutral(effect: str, parameter: str) -> float | None:
    base = parameter.split("[", 1)[0]
    if (effect, base) in NO_NEUTRAL:
        return None
    return NEUTRAL.get((effect, base), 0.0)


def outliers(
    table: pd.DataFrame,
    *,
    z_outlier: float = 4.0,
    rel_floor: float = 0.05,
    min_robots: int = 4,
    drift_table: pd.DataFrame | None = None,
    **drift_kwargs: float,
) -> pd.DataFrame:
    """The fleet's robust z of every robot, day and series (see the module's text), one row
    each: ``day, robot, effect, joint, parameter, value, present, median, spread, scale, z,
    drifting, outlier`` (``scale`` = ``s_i``). ``present`` is False where the robot's diagnosis did not select the effect
    (value = the neutral value). ``drift_table`` (default: :func:`drift` of the same table
    with ``drift_kwargs``) marks the series reported as drift instead."""
    s = series_table(table)
    diagnosed = table.loc[table["status"] == "ok", ["robot", "day"]].drop_duplicates()
    if drift_table is None:
        drift_table = drift(table, **drift_kwargs)  # type: ignore[arg-type]
    drifting = {tuple(r) for r in drift_table.loc[drift_table["drifting"], ["robot", *KEY]].itertuples(index=False)}
    rows = []
    for (effect, joint, parameter), g in s.groupby(KEY, sort=True):
        neutral = _neutral(str(effect), str(parameter))
        for day, robots in diagnosed.groupby("day", sort=True):
            have = g[g["day"] == day].set_index("robot")
            names = list(robots["robot"])
            values, sigmas, present = [], [], []
            fill = neutral is not None and 2 * sum(r in have.index for r in names) < len(names)
            for robot in names:
                if robot in have.index:
                    values.append(float(have.at[robot, "value"]))
                    sigmas.append(float(have.at[robot, "sigma"]))
                    present.append(True)
                elif fill:
                    values.append(float(neutral))  # type: ignore[arg-type]
                    sigmas.append(0.0)
                    present.append(False)
                else:
                    values.append(math.nan)
                    sigmas.append(math.nan)
                    present.append(False)
            x = np.asarray(values)
            finite = np.isfinite(x)
            if finite.sum() < min_robots or not any(present):
                continue
            median = float(np.median(x[finite]))
            mad = float(np.median(np.abs(x[finite] - median)))
            spread = max(1.4826 * mad, rel_floor * abs(median))
            for robot, v, sig, p in zip(names, values, sigmas, present):
                if not math.isfinite(v):
                    continue
                sig = sig if math.isfinite(sig) else 0.0
                scale = math.sqrt(spread**2 + sig**2)
                z = (v - median) / scale if scale > 0 else (0.0 if v == median else math.copysign(math.inf, v - median))
                d = (robot, effect, joint, parameter) in drifting
                rows.append({"day": day, "robot": robot, "effect": effect, "joint": joint, "parameter": parameter, "value": v, "present": p, "median": median, "spread": spread, "scale": scale, "z": z, "drifting": d, "outlier": bool(abs(z) >= z_outlier and not d)})
    cols = ["day", "robot", *KEY, "value", "present", "median", "spread", "scale", "z", "drifting", "outlier"]
    return pd.DataFrame(rows, columns=cols).astype({"present": bool, "drifting": bool, "outlier": bool})
