"""The fleet's results: the table of every robot-day's effects, the robot-days themselves and
their reports (:class:`FleetResult`), built from the task results of :mod:`simgap.fleet.run`
or read back from an output folder.

The table has one row per robot, day, selected effect, joint and parameter (columns
:data:`TABLE_COLUMNS`). Units come from :mod:`simgap.fleet.vocabulary` and follow the joint
type (read from the URDF on the worker); counts such as ``identifiable_directions`` are not
rows; a value the report gives without a finite interval (an unresolved centre-of-mass
coordinate) is a row with ``identified = False``, which no test reads.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pandas as pd

from . import vocabulary

__all__ = ["KSTEP_HORIZON_S", "TABLE_COLUMNS", "TASK_COLUMNS", "FleetResult", "report_rows"]

KSTEP_HORIZON_S = 0.5
"""The k-step horizon reported in the table's ``kstep_*`` columns (the nearest one the report has)."""

TABLE_COLUMNS = [
    "robot", "day", "effect", "joint", "joint_type", "parameter", "value", "uncertainty", "unit", "identified",
    "kstep_horizon_s", "kstep_before", "kstep_after", "kstep_floor", "l2_before", "l2_after",
    "status", "error",
]  # fmt: skip

TASK_COLUMNS = [
    "robot", "day", "status", "error", "effects", "headline", "l2_before", "l2_after", "kstep_horizon_s", "kstep_before",
    "kstep_after", "seconds", "cpu_seconds", "rss_start_mb", "peak_rss_mb", "worker",
]  # fmt: skip


def _num(x: Any) -> float:
    try:
        return math.nan if x is None else float(x)
    except (TypeError, ValueError):
        return math.nan


def _kstep(gap: dict[str, Any]) -> tuple[float, float, float, float]:
    """(horizon, before, after, floor) of the held-out k-step error nearest KSTEP_HORIZON_S;
    NaN where the report has no ``gap.kstep``."""
    kstep = gap.get("kstep") if isinstance(gap, dict) else None
    if not isinstance(kstep, dict) or not kstep.get("horizons_s"):
        return (math.nan,) * 4
    horizons = [_num(h) for h in kstep["horizons_s"]]
    i = min(range(len(horizons)), key=lambda k: abs(horizons[k] - KSTEP_HORIZON_S) if not math.isnan(horizons[k]) else math.inf)

    def at(name: str) -> float:
        values = kstep.get(name) or []
        return _num(values[i]) if i < len(values) else math.nan

    return horizons[i], at("before"), at("after"), at("floor")


def _values(joints: list[str], value: Any, uncertainty: Any) -> Iterator[tuple[str, str, float, float]]:
    """(joint, component suffix, value, uncertainty) of one parameter: per joint when a list
    aligned with ``joints``, per component for vectors (``com[0]``), else a whole-robot number."""
    if isinstance(value, list):
        unc = uncertainty if isinstance(uncertainty, list) and len(uncertainty) == len(value) else [None] * len(value)
        aligned = bool(joints) and len(value) == len(joints)
        for i, (v, u) in enumerate(zip(value, unc)):
            joint = joints[i] if aligned else ""
            if isinstance(v, list):  # per link, a vector each
                uu = u if isinstance(u, list) and len(u) == len(v) else [None] * len(v)
                for k, (vk, uk) in enumerate(zip(v, uu)):
                    yield joint, f"[{k}]", _num(vk), _num(uk)
            else:
                yield joint, "" if aligned else f"[{i}]", _num(v), _num(u)
    else:
        yield "", "", _num(value), _num(uncertainty)


def report_rows(robot: str, day: str, report: dict[str, Any] | None, status: str = "ok", error: str = "", joint_types: dict[str, str] | None = None) -> list[dict[str, Any]]:
    """The table rows of one robot-day (columns :data:`TABLE_COLUMNS`): one per selected
    effect, joint and parameter; a single row with no effect when nothing was selected or the
    task failed, so every robot-day appears.

    ``joint_types`` (joint name -> ``"revolute"`` / ``"prismatic"``, from the URDF) sets each
    row's ``joint_type`` and unit (:func:`vocabulary.unit`); without it, the report's ``units``
    (else the revolute unit). Counts and settings (:func:`vocabulary.is_parameter` False:
    ``identifiable_directions``, ``periods_per_rev``, ``w``) are left out (the full report keeps
    them); a
    value without a finite, positive uncertainty has ``identified = False``. Reads the report
    defensively: keys a report does not have (``gap.kstep``, ``units``) give NaN / the
    vocabulary's unit."""
    gap = (report or {}).get("gap") or {}
    horizon, k_before, k_after, k_floor = _kstep(gap)
    common = {
        "robot": robot, "day": day, "kstep_horizon_s": horizon, "kstep_before": k_before, "kstep_after": k_after,
        "kstep_floor": k_floor, "l2_before": _num(gap.get("holdout_l2_before")), "l2_after": _num(gap.get("holdout_l2_after")),
        "status": status, "error": error,
    }  # fmt: skip
    types = joint_types or {}
    rows = []
    for effect in (report or {}).get("selected_effects") or []:
        name_of_effect = str(effect.get("effect", ""))
        joints = list(effect.get("joints") or [])
        units = effect.get("units") or {}
        uncertainty = effect.get("uncertainty") or {}
        for name, value in (effect.get("parameters") or {}).items():
            if not vocabulary.is_parameter(name_of_effect, name):
                continue  # a count or a setting, not a parameter
            for joint, suffix, v, u in _values(joints, value, uncertainty.get(name)):
                joint_type = types.get(joint, "") if joint else ""
                unit = vocabulary.unit(name_of_effect, name, joint_type) if (joint_type or name not in units) else str(units[name])
                identified = bool(math.isfinite(v) and math.isfinite(u) and u > 0)
                rows.append({**common, "effect": name_of_effect, "joint": joint, "joint_type": joint_type, "parameter": name + suffix, "value": v, "uncertainty": u, "unit": unit or str(units.get(name, "")), "identified": identified})
    if not rows:
        rows.append({**common, "effect": None, "joint": None, "joint_type": None, "parameter": None, "value": math.nan, "uncertainty": math.nan, "unit": None, "identified": False})
    return [{c: row[c] for c in TABLE_COLUMNS} for row in rows]


def _table(rows: list[dict[str, Any]]) -> pd.DataFrame:
    df = pd.DataFrame(rows, columns=TABLE_COLUMNS)
    return df.sort_values(["robot", "day", "effect", "joint", "parameter"], kind="stable", na_position="first").reset_index(drop=True)


class FleetResult:
    """The fleet's diagnoses: ``table`` (one row per robot, day, effect, joint, parameter;
    columns :data:`TABLE_COLUMNS`), ``tasks`` (one row per robot-day: status, error, seconds,
    peak memory, worker, selected effects, gap figures) and ``reports`` (the JSON report of
    each successful robot-day, keyed by ``(robot, day)``)."""

    def __init__(self, table: pd.DataFrame, tasks: pd.DataFrame, reports: dict[tuple[str, str], dict[str, Any]] | None = None, wall_seconds: float = math.nan, workers: int = 0) -> None:
        self.table = table
        self.tasks = tasks
        self.reports = reports or {}
        self.wall_seconds = wall_seconds
        self.workers = workers

    @classmethod
    def from_results(cls, results: list[dict[str, Any]], wall_seconds: float = math.nan, workers: int = 0) -> FleetResult:
        """Builds the tables from the task result dicts (:func:`simgap.fleet.diagnose_task`)."""
        results = sorted(results, key=lambda r: (r["robot"], r["day"]))
        reports = {(r["robot"], r["day"]): r["report"] for r in results if r.get("report")}
        rows: list[dict[str, Any]] = []
        tasks = []
        for r in results:
            rows.extend(report_rows(r["robot"], r["day"], r.get("report"), r["status"], r.get("error", ""), r.get("joint_types")))
            report = r.get("report") or {}
            gap = report.get("gap") or {}
            horizon, k_before, k_after, _ = _kstep(gap)
            tasks.append(
                {
                    "robot": r["robot"], "day": r["day"], "status": r["status"], "error": r.get("error", ""),
                    "effects": ", ".join(e.get("effect", "") for e in report.get("selected_effects") or []),
                    "headline": str(gap.get("headline") or ""),
                    "l2_before": _num(gap.get("holdout_l2_before")), "l2_after": _num(gap.get("holdout_l2_after")),
                    "kstep_horizon_s": horizon, "kstep_before": k_before, "kstep_after": k_after,
                    "seconds": _num(r.get("seconds")), "cpu_seconds": _num(r.get("cpu_seconds")), "rss_start_mb": _num(r.get("rss_start_mb")), "peak_rss_mb": _num(r.get("peak_rss_mb")),
                    "worker": r.get("worker", ""),
                }  # fmt: skip
            )
        return cls(_table(rows), pd.DataFrame(tasks, columns=TASK_COLUMNS), reports, wall_seconds, workers)

    @classmethod
    def read(cls, folder: str | os.PathLike[str]) -> FleetResult:
        """Reads what ``python -m simgap.fleet … --out FOLDER`` wrote (``fleet.parquet`` or
        ``fleet.csv``, ``tasks.csv``, ``reports/``), e.g. to re-run the analysis with other
        thresholds."""
        folder = Path(folder)
        parquet = folder / "fleet.parquet"
        table = pd.read_parquet(parquet) if parquet.exists() else pd.read_csv(folder / "fleet.csv", dtype={"day": str})
        text = ("robot", "day", "status", "error", "effects", "headline", "worker")
        tasks = pd.read_csv(folder / "tasks.csv", dtype={c: str for c in text}, keep_default_na=False, na_values={c: [""] for c in TASK_COLUMNS if c not in text})
        for column, fill in (("joint_type", ""), ("identified", None)):  # tables of earlier versions
            if column not in table.columns:
                table[column] = fill
        if table["identified"].isna().any():
            unc = pd.to_numeric(table["uncertainty"], errors="coerce")
            table["identified"] = (unc > 0) & unc.map(math.isfinite)
        table = table[TABLE_COLUMNS]
        reports = {}
        for path in sorted((folder / "reports").glob("*/*.json")):
            reports[(path.parent.name, path.stem)] = json.loads(path.read_text())
        return cls(table, tasks, reports)

    @property
    def failed(self) -> pd.DataFrame:
        """The robot-days that failed, with their errors."""
        return self.tasks[self.tasks["status"] != "ok"].reset_index(drop=True)

    def to_parquet(self, path: str | os.PathLike[str]) -> None:
        """Writes :attr:`table` to Parquet (needs pyarrow)."""
        self.table.to_parquet(path, index=False)

    def findings(self, **thresholds: Any) -> pd.DataFrame:
        """One row per finding (change over the days, effect against neutral, outlier against
        the fleet), with the report's alternatives: see :func:`simgap.fleet.find`."""
        from .findings import find

        return find(self.table, self.reports, **thresholds).flags

    def drift(self, **kwargs: Any) -> pd.DataFrame:
        """Per robot and parameter, the trend and step tests over days: see :func:`simgap.fleet.drift`."""
        from .trends import drift

        return drift(self.table, **kwargs)

    def outliers(self, **kwargs: Any) -> pd.DataFrame:
        """Per day, robot and parameter, against the fleet or the neutral value: see :func:`simgap.fleet.outliers`."""
        from .trends import outliers

        return outliers(self.table, **kwargs)

    def to_html(self, path: str | os.PathLike[str], **kwargs: Any) -> None:
        """Writes the self-contained HTML fleet report: see :func:`simgap.fleet.write_html`."""
        from .report import write_html

        write_html(self, path, **kwargs)

    def __repr__(self) -> str:
        ok = int((self.tasks["status"] == "ok").sum())
        return f"<FleetResult {ok}/{len(self.tasks)} robot-days diagnosed, {len(self.table)} rows>"
