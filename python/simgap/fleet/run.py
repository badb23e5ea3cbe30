"""Running the fleet: one Dask task per robot and day, results streamed as they finish.

The client only lists paths; workers load the URDF and read the logs themselves, so logs must
be on a filesystem every worker sees (the same path on every machine). A task that fails on
its data (a ``SimgapError``: unreadable log, too short, failed fit) is recorded with its error
and the others go on; a task that raises anything else is re-run up to ``retries`` times; a
task whose worker dies is re-run elsewhere by the scheduler (Dask's ``allowed-failures``).
"""

from __future__ import annotations

import json
import logging
import math
import os
import signal
import socket
import threading
import time
import uuid
from collections.abc import Callable, Generator
from functools import lru_cache
from pathlib import Path
from typing import Any

import pandas as pd

import simgap

from .index import Task, index_from_folder, index_from_table, tasks_from_index
from .result import FleetResult

__all__ = ["diagnose_fleet", "diagnose_task", "iter_fleet"]

# --- on the worker --------------------------------------------------------------------------


@lru_cache(maxsize=8)
def _model(urdf: str, tip: str | None, mtime: float) -> simgap.Model:
    """The model, loaded once per worker process (``mtime`` invalidates an edited file)."""
    return simgap.Model.from_urdf(urdf, tip=tip)


def _joint_types(urdf: str, mtime: float) -> dict[str, str]:
    """Joint name -> ``"revolute"`` / ``"prismatic"`` of the URDF's movable joints (continuous
    joints are revolute), for the units of the table."""
    return dict(_joint_types_cached(urdf, mtime))


@lru_cache(maxsize=8)
def _joint_types_cached(urdf: str, mtime: float) -> tuple[tuple[str, str], ...]:
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(urdf).getroot()
    except (OSError, ET.ParseError):
        return ()  # the model loader reports a broken URDF with its own error
    out = []
    for joint in root.iter("joint"):
        kind = joint.get("type", "")
        if kind in ("revolute", "continuous", "prismatic"):
            out.append((joint.get("name", ""), "prismatic" if kind == "prismatic" else "revolute"))
    return tuple(out)


def _read(path: str, joints: list[str], read_options: dict[str, Any]) -> simgap.Run:
    """Reads one log on the worker with :func:`simgap.read_log`, which reads MCAP files,
    rosbag2 bag folders, CSV (``.csv.gz`` too) and one episode of a LeRobot dataset
    (``FOLDER#N``) with the log's experiment (its metadata or its sidecar
    ``NAME.experiment.json``, a dataset's ``meta/simgap.experiment.json``). ``read_options``
    may hold ``calibration``, LeRobot's calibration file."""
    return simgap.read_log(Path(path), joints=joints, **read_options)


def _read_all(path: str, joints: list[str], read_options: dict[str, Any]) -> list[simgap.Run]:
    """Every run of one log, as :func:`_read` reads them: one per episode a LeRobot dataset
    path selects (a bare ``FOLDER`` or ``FOLDER#0-3`` in a table index), else the log's run."""
    return simgap.read_logs(Path(path), joints=joints, **read_options)


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


def diagnose_task(
    task: dict[str, Any],
    urdf: str,
    tip: str | None = None,
    formulation: str = "euler_lagrange",
    read_options: dict[str, Any] | None = None,
    diagnose_options: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Diagnoses one robot-day on the worker that runs it: loads the URDF, reads the logs of
    ``task`` (``{robot, day, fit: [paths], holdout: [paths]}``) and runs
    :func:`simgap.diagnose` (with the keyword arguments ``diagnose_options``, e.g.
    ``{"link_side_torque": True}``).

    Returns a dict of plain data: ``robot``, ``day``, ``status`` (``"ok"`` / ``"error"``),
    ``error`` (``"LogError: …"`` or ``""``), ``report`` (the JSON report as a dict, or None; with
    the key ``interval_variants``, :attr:`simgap.Report.interval_variants`),
    ``joint_types`` (joint name -> revolute / prismatic, from the URDF),
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
        mtime = os.path.getmtime(urdf)
        model = _model(str(urdf), tip, mtime)
        out["joint_types"] = _joint_types(str(urdf), mtime)
        fit = [run for p in task["fit"] for run in _read_all(p, model.joint_names, read_options or {})]
        holdout = [run for p in task["holdout"] for run in _read_all(p, model.joint_names, read_options or {})]
        report = simgap.diagnose(model, fit, holdout, formulation=formulation, **(diagnose_options or {}))  # type: ignore[arg-type]
        out["report"] = json.loads(report.to_json())
        # each interval method on its own, for the check's coverage comparison
        out["report"]["interval_variants"] = report.interval_variants
    except simgap.SimgapError as err:
        out["status"] = "error"
        out["error"] = f"{type(err).__name__}: {err}"
    out["seconds"] = time.perf_counter() - start
    out["finished_at"] = time.time()
    out["cpu_seconds"] = time.process_time() - cpu_start
    out["rss_start_mb"] = rss_start
    out["peak_rss_mb"] = _rss_mb("VmHWM") if exact_peak else math.nan
    return out


# --- on the client --------------------------------------------------------------------------


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
    diagnose_options: dict[str, Any] | None = None,
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
        future = client.submit(diagnose_task, spec, urdf, tip, formulation, read_options, diagnose_options, key=f"simgap-diagnose-{task.robot}-{task.day}-{uuid.uuid4().hex[:8]}", retries=retries, pure=False)
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


def _quiet_distributed_logs() -> None:
    """Raises the ``distributed`` loggers' console level to CRITICAL in this process."""
    for handler in logging.getLogger("distributed").handlers:
        if isinstance(handler, logging.StreamHandler):
            handler.setLevel(logging.CRITICAL)


class _SavedEnviron:
    """The values (or absence) of the variables a Dask nanny writes into this process's
    ``os.environ`` before it spawns a worker (``distributed.nanny.pre-spawn-environ``:
    ``RAYON_NUM_THREADS``, ``OMP_NUM_THREADS``, …) and never takes back. Left there, every
    later diagnosis of the caller (a ``simgap`` CLI it starts, or this process's first use of the
    diagnosis's thread pool) would run on one thread."""

    def __init__(self) -> None:
        import dask

        keys = list((dask.config.get("distributed.nanny.pre-spawn-environ", default={}) or {}).keys())
        self.values = {k: os.environ.get(k) for k in [*keys, "RAYON_NUM_THREADS"]}

    def restore(self) -> None:
        for k, v in self.values.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _close_quietly(client: Any, cluster: Any) -> None:
    """Closes a cluster this module started, without its shutdown chatter.

    A worker still busy when its scheduler goes away (Ctrl-C in the middle of a diagnosis)
    logs the lost heartbeat with a traceback; closing the cluster is this module's decision,
    so those lines say nothing to the user. The workers are told to keep quiet first (5 s at
    most: a worker that does not answer is closed anyway), then the cluster is closed.
    """
    from distributed.utils import silence_logging_cmgr

    def quiet_workers() -> None:
        try:
            client.run(_quiet_distributed_logs, on_error="ignore")
        except Exception:  # noqa: BLE001 - a cluster already half closed: nothing to quiet
            pass

    t = threading.Thread(target=quiet_workers, daemon=True)
    t.start()
    t.join(5.0)
    with silence_logging_cmgr(logging.CRITICAL):
        client.close()
        cluster.close()


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
    diagnose_options: dict[str, Any] | None = None,
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
    ``diagnose_options``: keyword arguments of :func:`simgap.diagnose` for every robot-day, e.g.
    ``{"link_side_torque": True}`` for arms whose logged effort is a joint-torque sensor's, or
    one of ``simgap.DIAGNOSE_SWITCHES`` set to True (friction that differs with the direction, for ball-screw axes).

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
                environ = _SavedEnviron()
                try:
                    own_cluster = LocalCluster(n_workers=n_workers or os.cpu_count() or 1, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address="127.0.0.1:0")
                finally:
                    environ.restore()
        finally:
            if main_thread:
                signal.signal(signal.SIGINT, previous)
        client = Client(own_cluster)
    try:
        workers = len(client.scheduler_info().get("workers", {}))
        start = time.perf_counter()
        results: list[dict[str, Any]] = []
        stream = iter_fleet(index, urdf, client, tip=tip, formulation=formulation, retries=retries, read_options=read_options, timeout=timeout, diagnose_options=diagnose_options)
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
            _close_quietly(client, own_cluster)
            # (a worker its nanny restarted set them again)
            environ.restore()
