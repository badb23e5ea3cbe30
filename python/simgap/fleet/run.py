"""Running the fleet: one Dask task per robot and day, results streamed as they finish.

The client only lists paths; workers load the URDF and read the logs themselves, so logs must
be on a filesystem every worker sees (the same path on every machine). A task that fails on
its data (a ``SimgapError``: unreadable log, too short, failed fit) is recorded with its error
and the others go on; a task that raises anything else is re-run up to ``retries`` times; a
task whose worker dies is re-run elsewhere by the scheduler (Dask's ``allowed-failures``).
"""

from __future__ import annotations

import json
import math
import os
import signal
import socket
import threading
import time
import uuid
from collections.abc import Callable, Generator, Iterator
from functools import lru_cache
from pathlib import Path
from typing import Any

import pandas as pd

import simgap

from .index import Task, index_from_folder, index_from_table, tasks_from_index

__all__ = ["FleetResult", "TABLE_COLUMNS", "diagnose_fleet", "diagnose_task", "iter_fleet", "report_rows"]

KSTEP_HORIZON_S = 0.5
"""The k-step horizon reported in the table's ``kstep_*`` columns (the nearest one the report has)."""

TABLE_COLUMNS = [
    "robot", "day", "effect", "joint", "parameter", "value", "uncertainty", "unit",
    "kstep_horizon_s", "kstep_before", "kstep_after", "kstep_floor", "l2_before", "l2_after",
    "status", "error",
]  # fmt: skip

TASK_COLUMNS = [
    "robot", "day", "status", "error", "effects", "headline", "l2_before", "l2_after", "kstep_horizon_s", "kstep_before",
    "kstep_after", "seconds", "cpu_seconds", "rss_start_mb", "peak_rss_mb", "worker",
]  # fmt: skip

# Units of the effects' parameters (the report's contract), for reports that carry no ``units``.
_UNITS = {
    "b": "N·m·s/rad", "fc": "N·m", "fs": "N·m", "vs": "rad/s", "ia": "kg·m²", "mass": "kg",
    "com": "m", "delta_mass": "kg", "delta_com": "m", "delta_inertia": "kg·m²", "k": "",
    "offset": "N·m", "limit": "N·m", "delay": "s", "amplitude": "N·m", "periods_per_rev": "",
}  # fmt: skip


# --- on the worker --------------------------------------------------------------------------


@lru_cache(maxsize=8)
def _model(urdf: str, tip: str | None, mtime: float) -> simgap.Model:
    """The model, loaded once per worker process (``mtime`` invalidates an edited file)."""
    return simgap.Model.from_urdf(urdf, tip=tip)


def _sidecar(path: Path) -> Path | None:
    """``NAME.experiment.json`` beside ``NAME.mcap`` / ``NAME.csv[.gz]`` / bag folder ``NAME``."""
    name = path.name
    for suffix in (".csv.gz", ".csv", ".mcap"):
        if name.lower().endswith(suffix):
            name = name[: -len(suffix)]
            break
    candidate = path.with_name(f"{name}.experiment.json")
    return candidate if candidate.is_file() else None


def _read(path: str, joints: list[str], read_options: dict[str, Any]) -> simgap.Run:
    """Reads one log on the worker, with its experiment sidecar when the log carries none."""
    p = Path(path)
    try:
        run = simgap.read_log(p, joints=joints, **read_options)
    except simgap.LogError:
        # a bag folder, for a simgap that does not read bags yet: its single MCAP file
        inner = sorted(p.glob("*.mcap")) if p.is_dir() else []
        if len(inner) != 1:
            raise
        run = simgap.read_log(inner[0], joints=joints, **read_options)
    sidecar = _sidecar(p)
    if run.experiment is None and sidecar is not None:
        try:
            experiment = {str(k): str(v) for k, v in json.loads(sidecar.read_text()).items()}
        except (OSError, ValueError, AttributeError) as err:
            raise simgap.LogError(f"{sidecar}: not a JSON object of experiment keys ({err})") from err
        run = simgap.Run(run.joints, run.t, run.q, run.qd, tau=run.tau, q_ref=run.q_ref, qd_ref=run.qd_ref, experiment=experiment, source=run.source)
    return run


def _reset_peak_rss() -> bool:
    """Resets this process's peak resident memory (Linux ``clear_refs``); False where unsupported."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def _rss_mb(field: str = "VmHWM") -> float:
    """This process's peak (``VmHWM``, since the last reset) or current (``VmRSS``) resident
    memory [MiB]; NaN where unknown."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return math.nan


def diagnose_task(task: dict[str, Any], urdf: str, tip: str | None = None, formulation: str = "euler_lagrange", read_options: dict[str, Any] | None = None) -> dict[str, Any]:
    """Diagnoses one robot-day on the worker that runs it: loads the URDF, reads the logs of
    ``task`` (``{robot, day, fit: [paths], holdout: [paths]}``) and runs
    :func:`simgap.diagnose`.

    Returns a dict of plain data: ``robot``, ``day``, ``status`` (``"ok"`` / ``"error"``),
    ``error`` (``"LogError: …"`` or ``""``), ``report`` (the JSON report as a dict, or None),
    ``seconds`` (wall time), ``cpu_seconds`` (the worker process's CPU time), ``rss_start_mb`` and ``peak_rss_mb`` (the worker's resident
    memory when the task started and its peak during the task: the difference is the task's
    own memory, meaningful with one thread per worker), ``worker`` (host:pid), ``finished_at`` (epoch seconds). A ``SimgapError`` is
    recorded, not raised; anything else raises (and Dask retries it).
    """
    start = time.perf_counter()
    exact_peak = _reset_peak_rss()
    rss_start = _rss_mb("VmRSS")
    cpu_start = time.process_time()
    out: dict[str, Any] = {"robot": task["robot"], "day": task["day"], "status": "ok", "error": "", "report": None, "worker": f"{socket.gethostname()}:{os.getpid()}"}
    try:
        model = _model(str(urdf), tip, os.path.getmtime(urdf))
        fit = [_read(p, model.joint_names, read_options or {}) for p in task["fit"]]
        holdout = [_read(p, model.joint_names, read_options or {}) for p in task["holdout"]]
        report = simgap.diagnose(model, fit, holdout, formulation=formulation)  # type: ignore[arg-type]
        out["report"] = json.loads(report.to_json())
    except simgap.SimgapError as err:
        out["status"] = "error"
        out["error"] = f"{type(err).__name__}: {err}"
    out["seconds"] = time.perf_counter() - start
    out["finished_at"] = time.time()
    out["cpu_seconds"] = time.process_time() - cpu_start
    out["rss_start_mb"] = rss_start
    out["peak_rss_mb"] = _rss_mb("VmHWM") if exact_peak else math.nan
    return out


# --- from a report to rows -------------------------------------------------------------------


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


def report_rows(robot: str, day: str, report: dict[str, Any] | None, status: str = "ok", error: str = "") -> list[dict[str, Any]]:
    """The table rows of one robot-day (columns :data:`TABLE_COLUMNS`): one per selected
    effect, joint and parameter; a single row with no effect when nothing was selected or the
    task failed, so every robot-day appears. Reads the report defensively: keys a report does
    not have (``gap.kstep``, ``units``) give NaN / the contract's unit."""
    gap = (report or {}).get("gap") or {}
    horizon, k_before, k_after, k_floor = _kstep(gap)
    common = {
        "robot": robot, "day": day, "kstep_horizon_s": horizon, "kstep_before": k_before, "kstep_after": k_after,
        "kstep_floor": k_floor, "l2_before": _num(gap.get("holdout_l2_before")), "l2_after": _num(gap.get("holdout_l2_after")),
        "status": status, "error": error,
    }  # fmt: skip
    rows = []
    for effect in (report or {}).get("selected_effects") or []:
        joints = list(effect.get("joints") or [])
        units = effect.get("units") or {}
        uncertainty = effect.get("uncertainty") or {}
        for name, value in (effect.get("parameters") or {}).items():
            for joint, suffix, v, u in _values(joints, value, uncertainty.get(name)):
                rows.append({**common, "effect": effect.get("effect", ""), "joint": joint, "parameter": name + suffix, "value": v, "uncertainty": u, "unit": str(units.get(name, _UNITS.get(name, "")))})
    if not rows:
        rows.append({**common, "effect": None, "joint": None, "parameter": None, "value": math.nan, "uncertainty": math.nan, "unit": None})
    return [{c: row[c] for c in TABLE_COLUMNS} for row in rows]


def _table(rows: list[dict[str, Any]]) -> pd.DataFrame:
    df = pd.DataFrame(rows, columns=TABLE_COLUMNS)
    return df.sort_values(["robot", "day", "effect", "joint", "parameter"], kind="stable", na_position="first").reset_index(drop=True)


# --- on the client --------------------------------------------------------------------------


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
        """Builds the tables from the task result dicts (:func:`diagnose_task`)."""
        results = sorted(results, key=lambda r: (r["robot"], r["day"]))
        reports = {(r["robot"], r["day"]): r["report"] for r in results if r.get("report")}
        rows: list[dict[str, Any]] = []
        tasks = []
        for r in results:
            rows.extend(report_rows(r["robot"], r["day"], r.get("report"), r["status"], r.get("error", "")))
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

    def drift(self, **kwargs: Any) -> pd.DataFrame:
        """Per robot and parameter, the trend over days: see :func:`simgap.fleet.drift`."""
        from .trends import drift

        return drift(self.table, **kwargs)

    def outliers(self, **kwargs: Any) -> pd.DataFrame:
        """Per day, robot and parameter, the fleet's robust z: see :func:`simgap.fleet.outliers`."""
        from .trends import outliers

        return outliers(self.table, **kwargs)

    def to_html(self, path: str | os.PathLike[str], **kwargs: Any) -> None:
        """Writes the self-contained HTML fleet report: see :func:`simgap.fleet.write_html`."""
        from .report import write_html

        write_html(self, path, **kwargs)

    def __repr__(self) -> str:
        ok = int((self.tasks["status"] == "ok").sum())
        return f"<FleetResult {ok}/{len(self.tasks)} robot-days diagnosed, {len(self.table)} rows>"


def _progress(total: int, enabled: bool | Callable[[dict[str, Any]], None]) -> tuple[Callable[[dict[str, Any]], None], Callable[[], None]]:
    """(tick, close) of a progress display: tqdm when installed, else a ticking line on stderr."""
    if callable(enabled):
        return enabled, lambda: None
    if not enabled:
        return (lambda _r: None), (lambda: None)
    try:
        from tqdm.auto import tqdm

        bar = tqdm(total=total, unit="diagnosis", desc="fleet")

        def tick(r: dict[str, Any]) -> None:
            bar.set_postfix_str(f"{r['robot']} {r['day']} {r['status']}", refresh=False)
            bar.update(1)

        return tick, bar.close
    except ImportError:
        import sys

        done = [0]
        start = time.monotonic()
        sys.stderr.write(f"fleet: 0/{total} robot-days")
        sys.stderr.flush()

        def tick_plain(r: dict[str, Any]) -> None:
            done[0] += 1
            sys.stderr.write(f"\rfleet: {done[0]}/{total} robot-days, {time.monotonic() - start:.0f} s, last {r['robot']} {r['day']} {r['status']}   ")
            sys.stderr.flush()

        def close_plain() -> None:
            sys.stderr.write("\n")
            sys.stderr.flush()

        return tick_plain, close_plain


def _index(index: pd.DataFrame | str | os.PathLike[str]) -> pd.DataFrame:
    if isinstance(index, (str, os.PathLike)):
        return index_from_folder(index)
    return index_from_table(index)


def iter_fleet(
    index: pd.DataFrame | str | os.PathLike[str],
    urdf: str | os.PathLike[str],
    client: Any,
    *,
    tip: str | None = None,
    formulation: str = "euler_lagrange",
    retries: int = 2,
    read_options: dict[str, Any] | None = None,
    timeout: float | None = None,
) -> Generator[dict[str, Any], None, None]:
    """Submits one task per robot-day of ``index`` to the Dask ``client`` and yields each
    task's result dict (see :func:`diagnose_task`) as it finishes, in completion order.

    Robot-days that cannot run (a single log) are yielded first, as errors, without being
    submitted; a task that fails after its retries (or whose workers keep dying) is yielded as
    an error with the exception's text. Closing the generator (or Ctrl-C) cancels what has
    not run. ``timeout`` [s]: the longest wait for the next result (``TimeoutError`` past it).
    """
    from distributed import as_completed

    urdf = str(Path(urdf).resolve())
    todo: list[Task] = []
    for task in tasks_from_index(_index(index)):
        problem = task.problem()
        if problem:
            yield {"robot": task.robot, "day": task.day, "status": "error", "error": f"FitError: {problem}", "report": None, "seconds": math.nan, "peak_rss_mb": math.nan, "worker": ""}
        else:
            todo.append(task)
    futures = []
    task_of = {}
    for task in todo:
        spec = {"robot": task.robot, "day": task.day, "fit": task.fit, "holdout": task.holdout}
        future = client.submit(diagnose_task, spec, urdf, tip, formulation, read_options, key=f"simgap-diagnose-{task.robot}-{task.day}-{uuid.uuid4().hex[:8]}", retries=retries, pure=False)
        futures.append(future)
        task_of[future.key] = task
    finished: set[str] = set()
    try:
        # results are fetched in the background as tasks finish (with_results), ~3x less
        # per-task overhead on the client than fetching each one after it is yielded
        for future, value in as_completed(futures, timeout=timeout, with_results=True, raise_errors=False):
            finished.add(future.key)
            task = task_of[future.key]
            if future.status == "error" or isinstance(value, BaseException):
                err = value if isinstance(value, BaseException) else future.exception()
                value = {"robot": task.robot, "day": task.day, "status": "error", "error": f"{type(err).__name__}: {err}", "report": None, "seconds": math.nan, "peak_rss_mb": math.nan, "worker": ""}
            future.release()
            yield value
    finally:
        # closed early (Ctrl-C, an exception in the consumer): what has not run is cancelled
        unfinished = [f for f in futures if f.key not in finished]
        if unfinished:
            client.cancel(unfinished)


def diagnose_fleet(
    index: pd.DataFrame | str | os.PathLike[str],
    urdf: str | os.PathLike[str],
    client: Any = None,
    *,
    tip: str | None = None,
    formulation: str = "euler_lagrange",
    retries: int = 2,
    progress: bool | Callable[[dict[str, Any]], None] = False,
    read_options: dict[str, Any] | None = None,
    n_workers: int | None = None,
    timeout: float | None = None,
) -> FleetResult:
    """Diagnoses every robot on every day of ``index`` on a Dask cluster.

    ``index``: a fleet index (:func:`index_from_table`) or a folder ``ROBOT/DAY/…``
    (:func:`index_from_folder`). ``urdf``: the robot model, a path every worker can read
    (``tip`` as in :meth:`simgap.Model.from_urdf`). ``client``: a ``distributed.Client``; when
    None, a ``LocalCluster`` on 127.0.0.1 of ``n_workers`` (default: the machine's cores)
    worker processes of one thread each (``RAYON_NUM_THREADS=1`` unless set) is started and
    closed afterwards. ``retries``: re-runs of a task that raised something other than a
    ``SimgapError``. ``progress``: True for a progress bar
    (tqdm when installed), or a callable called with each result dict. ``read_options``:
    extra keyword arguments of :func:`simgap.read_log` on the workers. ``timeout`` [s]: the
    longest wait for the next result (``TimeoutError`` past it; None waits as long as it takes).

    Returns a :class:`FleetResult`; failed robot-days are in it with their errors.
    """
    index = _index(index)
    own_cluster = None
    if client is None:
        import dask
        from distributed import Client, LocalCluster

        # one core per worker: one thread, and the diagnosis's own thread pool held to one;
        # worker processes started with Ctrl-C ignored (inherited), so that Ctrl-C in a
        # terminal reaches this process only, which stops the cluster in order
        main_thread = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main_thread else None
        try:
            with dask.config.set({"distributed.nanny.pre-spawn-environ.RAYON_NUM_THREADS": os.environ.get("RAYON_NUM_THREADS", "1")}):
                own_cluster = LocalCluster(n_workers=n_workers or os.cpu_count() or 1, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address="127.0.0.1:0")
        finally:
            if main_thread:
                signal.signal(signal.SIGINT, previous)
        client = Client(own_cluster)
    try:
        workers = len(client.scheduler_info().get("workers", {}))
        start = time.perf_counter()
        results: list[dict[str, Any]] = []
        stream = iter_fleet(index, urdf, client, tip=tip, formulation=formulation, retries=retries, read_options=read_options, timeout=timeout)
        tasks_total = len(tasks_from_index(index))
        tick, close = _progress(tasks_total, progress)
        try:
            for result in stream:
                results.append(result)
                tick(result)
        finally:
            stream.close()
            close()
        return FleetResult.from_results(results, time.perf_counter() - start, workers)
    finally:
        if own_cluster is not None:
            client.close()
            own_cluster.close()
