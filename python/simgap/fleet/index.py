"""The fleet index: which logs belong to which robot and day, and which of them are held out.

A fleet index is a pandas DataFrame with one row per log and the columns

- ``robot``: the robot's name,
- ``day``: the day the log was recorded, as text (``YYYY-MM-DD`` sorts and parses as a date;
  any other text sorts by name),
- ``path``: the log (``.mcap``, ``.csv``, ``.csv.gz``, a rosbag2 bag folder, or one episode
  ``FOLDER#N`` of a LeRobot dataset),
- ``role``: ``"fit"`` or ``"holdout"``.

The rule that assigns roles when none are given (:data:`HOLDOUT_RULE`): within each robot and
day, logs sorted by their path, the **last** one is held out and the others are fitted. A
robot-day with a single log cannot be diagnosed (nothing to fit, or nothing to check on) and
is reported as failed.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

__all__ = ["HOLDOUT_RULE", "LOG_SUFFIXES", "Task", "index_from_folder", "index_from_table", "tasks_from_index"]

HOLDOUT_RULE = "per robot and day, logs sorted by path: the last is held out, the others are fitted"
LOG_SUFFIXES = (".mcap", ".csv", ".csv.gz")
COLUMNS = ["robot", "day", "path", "role"]


def _is_bag(path: Path) -> bool:
    """A rosbag2 bag: a folder with ``metadata.yaml``."""
    return path.is_dir() and (path / "metadata.yaml").is_file()


def _is_lerobot(path: Path) -> bool:
    """A LeRobot dataset: a folder with ``meta/info.json``."""
    return path.is_dir() and (path / "meta" / "info.json").is_file()


def _episodes(path: Path) -> list[str]:
    """One log per episode of a LeRobot dataset, ``FOLDER#N`` (sorted by path, the last
    episode is the one held out)."""
    import simgap

    return [f"{path}#{e}" for e in simgap.lerobot_episodes(path)]


def _is_log_file(path: Path) -> bool:
    name = path.name.lower()
    return path.is_file() and name.endswith(LOG_SUFFIXES)


def _logs_below(folder: Path) -> list[Path | str]:
    """Log files, bag folders and LeRobot dataset episodes below ``folder``, not descending
    into bags or datasets."""
    found: list[Path | str] = []
    for entry in sorted(folder.iterdir()):
        if entry.name.startswith("."):
            continue
        if _is_bag(entry):
            found.append(entry)
        elif _is_lerobot(entry):
            found.extend(_episodes(entry))
        elif entry.is_dir():
            found.extend(_logs_below(entry))
        elif _is_log_file(entry):
            found.append(entry)
    return found


def index_from_folder(root: str | os.PathLike[str]) -> pd.DataFrame:
    """The index of a folder laid out as ``ROOT/ROBOT/DAY/…``: every log file (``.mcap``,
    ``.csv``, ``.csv.gz``), bag folder (``metadata.yaml`` + ``.mcap``) and episode of a LeRobot
    dataset folder (``meta/info.json``; one row ``FOLDER#N`` per episode) found below a day
    folder, at any depth. Per-log experiments (``NAME.experiment.json`` beside the log, or the
    MCAP's own metadata) stay with the log and are read by the workers.

    Roles follow :data:`HOLDOUT_RULE`. Files directly in ``ROOT`` or ``ROBOT`` (a URDF, notes)
    are ignored. Raises FileNotFoundError when ``root`` is not a folder, ValueError when it
    holds no log.
    """
    root = Path(root)
    if not root.is_dir():
        raise FileNotFoundError(f"fleet folder {root} does not exist or is not a folder")
    rows = []
    for robot in sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith(".")):
        for day in sorted(p for p in robot.iterdir() if p.is_dir() and not p.name.startswith(".") and not _is_bag(p) and not _is_lerobot(p)):
            for log in _logs_below(day):
                rows.append({"robot": robot.name, "day": day.name, "path": str(log)})
    if not rows:
        raise ValueError(f"no log (.mcap, .csv, .csv.gz, bag folder or LeRobot dataset) found in {root}/ROBOT/DAY/")
    return index_from_table(pd.DataFrame(rows))


def index_from_table(table: pd.DataFrame | Iterable[dict[str, str]]) -> pd.DataFrame:
    """An index from a table with columns ``robot``, ``day``, ``path`` and, optionally,
    ``role`` (``"fit"`` / ``"holdout"``). Where ``role`` is missing or empty,
    :data:`HOLDOUT_RULE` decides for the robot-days that have no role at all; a robot-day
    where only some logs have a role is an error. Returns a new DataFrame sorted by robot, day
    and path. Raises ValueError for a missing column or an unknown role.
    """
    df = pd.DataFrame(table).copy()
    missing = [c for c in ("robot", "day", "path") if c not in df.columns]
    if missing:
        raise ValueError(f"fleet index: missing column(s) {', '.join(missing)}; expected robot, day, path[, role]")
    for c in ("robot", "day", "path"):
        df[c] = df[c].astype(str)
    if "role" not in df.columns:
        df["role"] = ""
    df["role"] = df["role"].fillna("").astype(str).str.strip().str.lower()
    bad = sorted(set(df["role"]) - {"", "fit", "holdout"})
    if bad:
        raise ValueError(f"fleet index: unknown role(s) {bad}; expected 'fit' or 'holdout'")
    df = df.sort_values(["robot", "day", "path"], kind="stable").reset_index(drop=True)
    for (robot, day), group in df.groupby(["robot", "day"], sort=False):
        given = group["role"] != ""
        if given.all():
            continue
        if given.any():
            raise ValueError(f"fleet index: {robot} {day}: some logs have a role and some do not; give all or none")
        df.loc[group.index, "role"] = "fit"
        df.loc[group.index[-1], "role"] = "holdout"
    return df[COLUMNS + [c for c in df.columns if c not in COLUMNS]]


@dataclass
class Task:
    """One diagnosis: the logs of one robot on one day."""

    robot: str
    day: str
    fit: list[str] = field(default_factory=list)
    holdout: list[str] = field(default_factory=list)

    @property
    def key(self) -> str:
        """A name unique in the fleet, used as the Dask key prefix."""
        return f"{self.robot}/{self.day}"

    def problem(self) -> str | None:
        """Why this task cannot run, or None."""
        if not self.fit:
            return "no fit log (a robot-day needs at least two logs: one fitted, one held out)"
        if not self.holdout:
            return "no held-out log"
        return None


def tasks_from_index(index: pd.DataFrame) -> list[Task]:
    """One :class:`Task` per robot and day of ``index``, in robot, day order."""
    index = index_from_table(index)
    tasks = []
    for (robot, day), group in index.groupby(["robot", "day"], sort=True):
        tasks.append(
            Task(
                str(robot),
                str(day),
                fit=group.loc[group["role"] == "fit", "path"].tolist(),
                holdout=group.loc[group["role"] == "holdout", "path"].tolist(),
            )
        )
    return tasks
