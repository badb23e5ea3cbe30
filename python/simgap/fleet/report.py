"""The HTML fleet report: self-contained (inline SVG plots), in the style of the diagnosis
report. First, per finding, the flagged robot's day-by-day series with its 95 % intervals,
the fleet band (or the neutral value it was judged against), the fitted line or step, and the
test that flagged it; then one plot per parameter compared across the fleet: every robot's
values with their 95 % bars, the fleet band (the daily median ± ``z_outlier`` robust spreads,
outside which a robot is an outlier), flagged robots drawn in colour and named in the legend.

Needs matplotlib (in the ``fleet`` extra)."""

from __future__ import annotations

import html
import io
import math
import os
from typing import Any, Protocol

import numpy as np
import pandas as pd

from . import trends
from .findings import Findings, find

__all__ = ["summary_text", "write_html"]

CSS = (
    "body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}"
    "table{border-collapse:collapse;margin:1em 0;font-size:90%}td,th{border:1px solid #ccc;padding:3px 8px;text-align:left;vertical-align:top}"
    "td.n{text-align:right;font-variant-numeric:tabular-nums}th{background:#f3f3f3}tr.bad{background:#fbeeee}"
    ".verdict{font-size:120%;padding:.7em;border-left:4px solid #2a7;background:#f4faf6}.meta{color:#666;font-size:90%}"
    "figure{margin:1em 0}figcaption{font-size:90%;color:#444}"
)
COLOURS = ["#d62728", "#1f77b4", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22"]


class FleetTables(Protocol):
    """What the report reads of a fleet's diagnoses (a :class:`simgap.fleet.FleetResult`): the
    report sits below the result, which offers it as ``to_html``, so it names only these."""

    @property
    def table(self) -> pd.DataFrame:
        """One row per robot, day, effect, joint, parameter."""
        ...

    @property
    def tasks(self) -> pd.DataFrame:
        """One row per robot-day: status, error, timings."""
        ...

    @property
    def reports(self) -> dict[tuple[str, str], dict[str, Any]]:
        """The JSON report of each successful robot-day, keyed by ``(robot, day)``."""
        ...

    @property
    def failed(self) -> pd.DataFrame:
        """The robot-days that failed, with their errors."""
        ...

    @property
    def wall_seconds(self) -> float:
        """Wall time of the fleet run [s] (NaN: not known)."""
        ...

    @property
    def workers(self) -> int:
        """Worker processes of the fleet run."""
        ...


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


def _finding_plot(robot: str, own: pd.DataFrame, scored: pd.DataFrame, change: Any, days: pd.DataFrame, title: str, unit: str, z_outlier: float) -> str:
    """One flagged robot's series of one parameter, day by day, as inline SVG text: its values
    with their 95 % intervals, the fleet band or the neutral value it was judged against, and
    the fitted line or step where a change was found."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8.5, 3.0), dpi=100)
    try:
        fleet = scored[scored["reference"] == "fleet"].drop_duplicates("day").sort_values("t")
        if len(fleet):
            ax.fill_between(fleet["t"], fleet["median"] - z_outlier * fleet["spread"], fleet["median"] + z_outlier * fleet["spread"], color="#2a7", alpha=0.15, lw=0, label=f"fleet band (median ± {z_outlier:g} robust spreads)")
            ax.plot(fleet["t"], fleet["median"], color="#2a7", lw=1, ls="--", label="fleet median")
        neutral = scored[scored["reference"] == "neutral"]
        if len(neutral):
            ax.axhline(float(neutral["median"].iloc[0]), color="#2a7", lw=1, ls="--", label=f"neutral value {float(neutral['median'].iloc[0]):g} (the fleet's)")
        own = own.sort_values("t")
        ax.errorbar(own["t"], own["value"], yerr=own["uncertainty"], color="#d62728", marker="o", ms=4, lw=1.4, capsize=3, label=f"{robot} (95 % intervals)", zorder=3)
        if change is not None and change.change == "trend":
            t = np.array([own["t"].min(), own["t"].max()])
            ax.plot(t, change.baseline + change.slope_per_day * (t - t[0]), color="#1f77b4", lw=1.2, label=f"trend {100 * change.rate_per_day:+.1f} %/day (z = {change.z:.1f})")
        elif change is not None and change.change == "step":
            k = float(own.loc[own["day"] == change.step_day, "t"].iloc[0])
            t0, t1 = float(own["t"].min()), float(own["t"].max())
            ax.plot([t0, k - 0.5, k - 0.5, t1], [change.step_before, change.step_before, change.step_after, change.step_after], color="#1f77b4", lw=1.2, label=f"step ×{change.step_ratio:.3g} from {change.step_day} (z = {change.step_z:.1f})")
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


TESTS = {
    "trend": "trend test: weighted line over the days, intervals at the fleet's scale, |z| ≥ {z_drift:g} and ≥ {rate:g} %/day",
    "step": "change-point test: best single split, intervals at the fleet's scale, |z| ≥ {z_drift:g} and a step ≥ {step:g} %",
    "neutral": "neutral test: against the effect's neutral value with the robot's own interval, |z| ≥ {z_outlier:g} (an effect the fleet does not have)",
    "fleet": "fleet test: robust z ≥ {z_outlier:g} against the fleet's median (MAD floored at {rel:g} % and the unit's minimum, with the robot's interval)",
}


def write_html(result: FleetTables, path: str | os.PathLike[str], *, findings: Findings | None = None, title: str = "fleet", **thresholds: Any) -> None:
    """Writes the fleet report of ``result`` to ``path``. ``findings`` (:func:`find` of the
    same result) is computed with ``thresholds`` (as in :func:`simgap.fleet.find`) when not
    given. Needs matplotlib."""
    import matplotlib  # noqa: F401 - fail before anything is written, with the module named

    table = result.table
    f = findings if findings is not None else find(table, result.reports, **thresholds)
    dr, ol, flags = f.drift, f.outliers, f.flags
    th = {"z_drift": 4.0, "min_rate_per_day": 0.02, "min_step": 0.10, "z_outlier": 4.0, "rel_floor": 0.05, "min_flagged_days": 2} | thresholds
    words = {k: v.format(z_drift=th["z_drift"], rate=100 * th["min_rate_per_day"], step=100 * th["min_step"], z_outlier=th["z_outlier"], rel=100 * th["rel_floor"]) for k, v in TESTS.items()}
    tasks = result.tasks
    ok = int((tasks["status"] == "ok").sum())
    robots = tasks["robot"].nunique()
    n_days = tasks["day"].nunique()
    h: list[str] = []
    h.append(f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>simgap fleet: {html.escape(title)}</title>\n<style>{CSS}</style></head><body>')
    h.append(f"<h1>simgap fleet report: <code>{html.escape(title)}</code></h1>")
    wall = f", {result.wall_seconds:.1f} s on {result.workers} worker(s)" if math.isfinite(result.wall_seconds) else ""
    h.append(f'<p class="meta">{robots} robots × {n_days} days: {ok} of {len(tasks)} robot-days diagnosed{wall}.</p>')
    if len(flags):
        names = sorted(set(flags["robot"]))
        h.append(f'<p class="verdict">{len(names)} robot(s) flagged: ' + "; ".join(f"<b>{html.escape(n)}</b> ({', '.join(sorted(set(flags.loc[flags['robot'] == n, 'finding'])))})" for n in names) + ".</p>")
        h.append("<h2>Findings</h2>" + _table_html(flags))
    else:
        h.append('<p class="verdict">No robot changes, carries an effect the fleet does not have, or stands out from the fleet.</p>')
    h.append(
        "<h2>Method</h2><p>Each robot-day is one diagnosis (fit logs / held-out logs); only parameters with a finite 95 % interval are tested "
        "(counts and directions the data do not resolve never are). <b>Changes over the days</b>, per robot and parameter: a "
        + html.escape(words["trend"]) + "; a " + html.escape(words["step"]) + "; where both hold, the smaller BIC names the change. "
        "The intervals' scale is calibrated on the fleet (the median reduced χ² of every robot's line), both ways. "
        "<b>Per day</b>, where at least half of the robots have the effect: " + html.escape(words["fleet"]) + "; where fewer do: " + html.escape(words["neutral"]) + ". "
        f"A per-day finding is reported once the robot is flagged on {th['min_flagged_days']:g} day(s). "
        "A parameter that changes over the days is reported once, as the change.</p>"
    )
    series = trends.series_table(table)
    days = pd.DataFrame({"day": sorted(set(tasks["day"]))})
    days["t"] = trends.day_numbers(days["day"])
    t_of_day = dict(zip(days["day"], days["t"]))
    series = series.assign(t=series["day"].map(t_of_day))
    ol = ol.assign(t=ol["day"].map(t_of_day))
    changes = {(r.robot, r.effect, r.joint, r.parameter): r for r in dr[dr["drifting"]].itertuples(index=False)}
    if len(flags):
        h.append('<h2>Flagged robots, day by day</h2><p class="meta">Each finding: the robot\'s values with their 95 % intervals, what it was judged against, and the test that flagged it.</p>')
        for r in flags.itertuples(index=False):
            key = (r.effect, r.joint, r.parameter)
            own = series[(series["robot"] == r.robot) & (series["effect"] == r.effect) & (series["joint"] == r.joint) & (series["parameter"] == r.parameter)]
            if own.empty:
                continue
            scored = ol[(ol["effect"] == r.effect) & (ol["joint"] == r.joint) & (ol["parameter"] == r.parameter)]
            unit = str(own["unit"].dropna().iloc[0]) if own["unit"].notna().any() else ""
            name = " · ".join(str(x) for x in key if x)
            svg = _finding_plot(r.robot, own, scored, changes.get((r.robot, *key)), days, f"{r.robot}: {name} ({r.finding} since {r.since})", unit, float(th["z_outlier"]))
            alt = f"<br>Also explained by (the robot-days' own reports): {html.escape(r.alternatives)}" if r.alternatives else ""
            h.append(f"<figure>{svg}<figcaption><b>{html.escape(r.robot)}</b>, {html.escape(name)} [{html.escape(unit)}]: {html.escape(r.detail)}.<br>Flagged by the {html.escape(words[r.test])}.{alt}</figcaption></figure>")
    h.append('<h2>Parameters over time</h2><p class="meta">One plot per parameter compared across the fleet; every value is in the table (Parquet).</p>')
    # one plot per parameter compared across the fleet (or flagged): not the coordinates of
    # an effect only one robot has, which stay in the table
    plotted = {tuple(k) for k in ol.loc[ol["reference"] == "fleet", trends.KEY].drop_duplicates().itertuples(index=False)} | {tuple(k) for k in flags[trends.KEY].itertuples(index=False)}
    for (effect, joint, parameter), g in series.groupby(trends.KEY, sort=True):
        key = (effect, joint, parameter)
        if key not in plotted:
            continue
        scored = ol[(ol["effect"] == effect) & (ol["joint"] == joint) & (ol["parameter"] == parameter)]
        band = scored.loc[scored["reference"] == "fleet", ["day", "t", "median", "spread"]].drop_duplicates("day")
        absent = scored[~scored["present"].astype(bool)]
        mark: dict[str, str] = {}
        for r in flags.itertuples(index=False):
            if (r.effect, r.joint, r.parameter) == key:
                mark[r.robot] = f"{r.finding} since {r.since}" if r.robot not in mark else mark[r.robot] + f", {r.finding}"
        unit = str(g["unit"].dropna().iloc[0]) if g["unit"].notna().any() else ""
        name = f"{effect} · {joint} · {parameter}" if joint else f"{effect} · {parameter}"
        h.append(f"<figure>{_plot(g, band, absent, days, mark, name, unit, float(th['z_outlier']))}<figcaption>{html.escape(name)} [{html.escape(unit)}], one point per robot-day with its 95 % bar.</figcaption></figure>")
    h.append("<h2>Robot-days</h2>")
    days_table = tasks[["robot", "day", "status", "effects", "l2_before", "l2_after", "kstep_horizon_s", "kstep_before", "kstep_after", "seconds", "error"]].rename(
        columns={"l2_before": "held-out L² before", "l2_after": "L² after", "kstep_horizon_s": "k-step horizon [s]", "kstep_before": "k-step error before", "kstep_after": "k-step after", "seconds": "task [s]"}
    )
    h.append(_table_html(days_table, bad=tasks["status"] != "ok"))
    h.append("<h2>Change tests</h2>" + _table_html(dr, bad=dr["drifting"]))
    h.append("</body></html>\n")
    with open(path, "w", encoding="utf-8") as out:
        out.write("\n".join(h))


def summary_text(result: FleetTables, findings: Findings | None = None, **thresholds: Any) -> str:
    """The terminal summary: robot-days, failures, findings."""
    flags = (findings if findings is not None else find(result.table, result.reports, **thresholds)).flags
    tasks = result.tasks
    lines = [f"{int((tasks['status'] == 'ok').sum())} of {len(tasks)} robot-days diagnosed ({tasks['robot'].nunique()} robots, {tasks['day'].nunique()} days)"]
    for r in result.failed.itertuples(index=False):
        lines.append(f"  FAILED {r.robot} {r.day}: {r.error}")
    if len(flags):
        with pd.option_context("display.width", 250, "display.max_columns", 20, "display.max_colwidth", 120):
            lines.append(flags[["robot", "finding", "effect", "joint", "parameter", "since", "test"]].to_string(index=False))
            lines.append("")
            for r in flags.itertuples(index=False):
                alt = f" [also explained by: {r.alternatives}]" if r.alternatives else ""
                lines.append(f"  {r.robot} {r.effect}{' ' + r.joint if r.joint else ''} {r.parameter}: {r.detail}{alt}")
    else:
        lines.append("no robot changes or stands out")
    return "\n".join(lines)
