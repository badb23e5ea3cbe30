"""The HTML fleet report: self-contained (inline SVG plots), in the style of the diagnosis
report. One plot per parameter over time: every robot's values with their 95 % bars, the
fleet band (the daily median ± ``z_outlier`` robust scales, the region outside which a robot is
an outlier), drifting and outlying robots drawn in colour and named in the legend."""

from __future__ import annotations

import html
import io
import math
import os
from typing import TYPE_CHECKING, Any

import pandas as pd

from . import trends

if TYPE_CHECKING:
    from .run import FleetResult

__all__ = ["write_html", "flagged_robots"]

CSS = (
    "body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}"
    "table{border-collapse:collapse;margin:1em 0;font-size:90%}td,th{border:1px solid #ccc;padding:3px 8px;text-align:left;vertical-align:top}"
    "td.n{text-align:right;font-variant-numeric:tabular-nums}th{background:#f3f3f3}tr.bad{background:#fbeeee}"
    ".verdict{font-size:120%;padding:.7em;border-left:4px solid #2a7;background:#f4faf6}.meta{color:#666;font-size:90%}"
    "figure{margin:1em 0}figcaption{font-size:90%;color:#444}"
)
COLOURS = ["#d62728", "#1f77b4", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22"]


def flagged_robots(drift: pd.DataFrame, outliers: pd.DataFrame) -> pd.DataFrame:
    """One row per finding: ``robot, finding ("drift" / "outlier"), effect, joint, parameter,
    since (first day flagged, or the first day of the trend), detail``."""
    rows = []
    for r in drift[drift["drifting"]].itertuples(index=False):
        rows.append({"robot": r.robot, "finding": "drift", "effect": r.effect, "joint": r.joint, "parameter": r.parameter, "since": r.first_day,
                     "detail": f"{r.slope_per_day:+.4g} ± {r.slope_se:.2g} per day ({100 * r.rate_per_day:+.1f} %/day, z = {r.z:.1f}) over {r.days} days"})  # fmt: skip
    flagged = outliers[outliers["outlier"]]
    for (robot, effect, joint, parameter), g in flagged.groupby(["robot", *trends.KEY], sort=True):
        days = sorted(g["day"])
        rows.append({"robot": robot, "finding": "outlier", "effect": effect, "joint": joint, "parameter": parameter, "since": days[0],
                     "detail": f"{len(days)} day(s): {', '.join(days)}; |z| up to {g['z'].abs().max():.1f}"})  # fmt: skip
    return pd.DataFrame(rows, columns=["robot", "finding", "effect", "joint", "parameter", "since", "detail"]).sort_values(["robot", "finding", "effect", "joint", "parameter"]).reset_index(drop=True)


def _plot(series: pd.DataFrame, band: pd.DataFrame, absent: pd.DataFrame, days: pd.DataFrame, highlight: dict[str, str], title: str, unit: str, z_outlier: float) -> str:
    """One parameter over days as inline SVG text."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8.5, 3.2), dpi=100)
    try:
        if len(band):
            band = band.sort_values("t")
            ax.fill_between(band["t"], band["median"] - z_outlier * band["spread"], band["median"] + z_outlier * band["spread"], color="#2a7", alpha=0.15, lw=0, label=f"fleet band (median ± {z_outlier:g} robust spreads)")
            ax.plot(band["t"], band["median"], color="#2a7", lw=1, ls="--", label="fleet median")
        colours = iter(COLOURS)
        for robot, g in series.groupby("robot", sort=True):
            g = g.sort_values("t")
            err = g["uncertainty"].where(g["uncertainty"].notna(), 0.0)
            if robot in highlight:
                ax.errorbar(g["t"], g["value"], yerr=err, color=next(colours, "#000"), marker="o", ms=4, lw=1.6, capsize=2, label=f"{robot} ({highlight[robot]})", zorder=3)
            else:
                ax.errorbar(g["t"], g["value"], yerr=err, color="#999", marker=".", ms=3, lw=0.7, capsize=1, alpha=0.8, zorder=2)
        ax.plot([], [], color="#999", marker=".", lw=0.7, label="other robots")
        if len(absent):
            ax.scatter(absent["t"], absent["value"], facecolors="none", edgecolors="#999", s=14, label="effect not selected (counted as neutral)", zorder=1)
        ax.set_xticks(days["t"], days["day"], fontsize=7, rotation=30 if len(days) > 6 else 0)
        ax.set_xlabel("day")
        ax.set_ylabel(unit or "value")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
        fig.tight_layout()
        buf = io.StringIO()
        fig.savefig(buf, format="svg")
        svg = buf.getvalue()
    finally:
        plt.close(fig)
    return svg[svg.index("<svg") :]


def _table_html(df: pd.DataFrame, bad: pd.Series | None = None) -> str:
    out = ["<table><tr>" + "".join(f"<th>{html.escape(str(c))}</th>" for c in df.columns) + "</tr>"]
    for i, row in enumerate(df.itertuples(index=False)):
        cls = ' class="bad"' if bad is not None and bool(bad.iloc[i]) else ""
        cells = []
        for v in row:
            if isinstance(v, float):
                cells.append(f'<td class="n">{"" if math.isnan(v) else f"{v:.4g}"}</td>')
            else:
                cells.append(f"<td>{html.escape(str(v))}</td>")
        out.append(f"<tr{cls}>" + "".join(cells) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def write_html(result: FleetResult, path: str | os.PathLike[str], *, z_drift: float = 4.0, min_rate_per_day: float = 0.02, z_outlier: float = 4.0, rel_floor: float = 0.05, title: str = "fleet") -> None:
    """Writes the fleet report of ``result`` to ``path`` (thresholds as in
    :mod:`simgap.fleet.trends`)."""
    table = result.table
    dr = trends.drift(table, z_drift=z_drift, min_rate_per_day=min_rate_per_day)
    ol = trends.outliers(table, z_outlier=z_outlier, rel_floor=rel_floor, drift_table=dr)
    flags = flagged_robots(dr, ol)
    tasks = result.tasks
    ok = int((tasks["status"] == "ok").sum())
    robots = tasks["robot"].nunique()
    days = tasks["day"].nunique()
    h: list[str] = []
    h.append(f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>simgap fleet: {html.escape(title)}</title>\n<style>{CSS}</style></head><body>')
    h.append(f"<h1>simgap fleet report: <code>{html.escape(title)}</code></h1>")
    wall = f", {result.wall_seconds:.1f} s on {result.workers} worker(s)" if math.isfinite(result.wall_seconds) else ""
    h.append(f'<p class="meta">{robots} robots × {days} days: {ok} of {len(tasks)} robot-days diagnosed{wall}.</p>')
    if len(flags):
        names = sorted(set(flags["robot"]))
        h.append(f'<p class="verdict">{len(names)} robot(s) flagged: ' + "; ".join(f"<b>{html.escape(n)}</b> ({', '.join(sorted(set(flags.loc[flags['robot'] == n, 'finding'])))})" for n in names) + ".</p>")
        h.append("<h2>Flagged robots</h2>" + _table_html(flags))
    else:
        h.append('<p class="verdict">No robot drifts or stands out from the fleet.</p>')
    h.append(
        f"<h2>Method</h2><p>Each robot-day is one diagnosis (fit logs / held-out logs). <b>Drift</b>: per robot and parameter, a weighted least-squares line over the days "
        f"on which the effect was selected (weights 1/σ², σ = 95 % half-width / 1.96, standard error inflated by √χ²ᵣ when the scatter exceeds σ); flagged when "
        f"|slope| ≥ {z_drift:g} standard errors and ≥ {100 * min_rate_per_day:g} % of the mean per day. <b>Outlier</b>: per day and parameter, robust z = (x − median) / "
        f"√(max(1.4826·MAD, {100 * rel_floor:g} % of |median|)² + σ²) across the robots diagnosed that day (where fewer than half of them have the effect, the others "
        f"count at its neutral value, 0 for most); flagged when |z| ≥ {z_outlier:g}, unless that robot's parameter is flagged as drift.</p>"
    )
    series = trends.series_table(table)
    days = pd.DataFrame({"day": sorted(set(tasks["day"]))})
    days["t"] = trends.day_numbers(days["day"])
    t_of_day = dict(zip(days["day"], days["t"]))
    series = series.assign(t=series["day"].map(t_of_day))
    ol = ol.assign(t=ol["day"].map(t_of_day))
    h.append("<h2>Parameters over time</h2><p class=\"meta\">One plot per parameter compared across the fleet; every value is in the table (Parquet).</p>")
    # one plot per parameter compared across the fleet (or drifting): not the coordinates of
    # an effect only one robot has, which stay in the table
    plotted = {tuple(k) for k in ol[trends.KEY].drop_duplicates().itertuples(index=False)} | {tuple(k) for k in dr.loc[dr["drifting"], trends.KEY].itertuples(index=False)}
    for (effect, joint, parameter), g in series.groupby(trends.KEY, sort=True):
        key = (effect, joint, parameter)
        if key not in plotted:
            continue
        scored = ol[(ol["effect"] == effect) & (ol["joint"] == joint) & (ol["parameter"] == parameter)]
        band = scored[["day", "t", "median", "spread"]].drop_duplicates("day")
        absent = scored[~scored["present"].astype(bool)]
        mark: dict[str, str] = {}
        for r in flags.itertuples(index=False):
            if (r.effect, r.joint, r.parameter) == key:
                mark[r.robot] = f"{r.finding} since {r.since}" if r.robot not in mark else mark[r.robot] + f", {r.finding}"
        unit = str(g["unit"].dropna().iloc[0]) if g["unit"].notna().any() else ""
        name = f"{effect} · {joint} · {parameter}" if joint else f"{effect} · {parameter}"
        h.append(f"<figure>{_plot(g, band, absent, days, mark, name, unit, z_outlier)}<figcaption>{html.escape(name)} [{html.escape(unit)}], one point per robot-day with its 95 % bar.</figcaption></figure>")
    h.append("<h2>Robot-days</h2>")
    days_table = tasks[["robot", "day", "status", "effects", "l2_before", "l2_after", "kstep_horizon_s", "kstep_before", "kstep_after", "seconds", "error"]].rename(
        columns={"l2_before": "held-out L² before [rad]", "l2_after": "L² after [rad]", "kstep_horizon_s": "k-step horizon [s]", "kstep_before": "k-step error before [rad]", "kstep_after": "k-step after [rad]", "seconds": "task [s]"}
    )
    h.append(_table_html(days_table, bad=tasks["status"] != "ok"))
    h.append("<h2>Trend tests</h2>" + _table_html(dr, bad=dr["drifting"]))
    h.append("</body></html>\n")
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(h))


def summary_text(result: FleetResult, **thresholds: Any) -> str:
    """The terminal summary: robot-days, failures, flagged robots."""
    dr = trends.drift(result.table, **{k: v for k, v in thresholds.items() if k in ("z_drift", "min_rate_per_day")})
    ol = trends.outliers(result.table, drift_table=dr, **{k: v for k, v in thresholds.items() if k in ("z_outlier", "rel_floor")})
    flags = flagged_robots(dr, ol)
    tasks = result.tasks
    lines = [f"{int((tasks['status'] == 'ok').sum())} of {len(tasks)} robot-days diagnosed ({tasks['robot'].nunique()} robots, {tasks['day'].nunique()} days)"]
    for r in result.failed.itertuples(index=False):
        lines.append(f"  FAILED {r.robot} {r.day}: {r.error}")
    if len(flags):
        with pd.option_context("display.width", 200, "display.max_columns", 20, "display.max_colwidth", 80):
            lines.append(flags.to_string(index=False))
    else:
        lines.append("no robot drifts or stands out")
    return "\n".join(lines)
