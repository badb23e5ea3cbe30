"""Fleet throughput on this machine: ``python -m simgap.fleet.bench [--workers 1 2]``.

Writes a synthetic fleet of the paper's arm (:mod:`simgap.fleet.synthetic` with its step log:
3 logs of 2.5 s per robot-day), then diagnoses it on a LocalCluster of each given number of single-threaded
workers and prints, per cluster size: robot-days, wall time (from the first submission to the
last result; cluster start-up excluded), diagnoses per minute and per core-minute (wall ×
workers), the median task's wall and CPU seconds, and memory per task (the worker's resident
memory at the task's start, and the peak increase during the task); then the time Dask itself
adds to each task (no-op tasks through the same path).
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
from pathlib import Path

import numpy as np


def _noop(i: int) -> int:
    return i


def scheduler_overhead(n_workers: int, tasks: int) -> float:
    """Wall seconds per task of ``tasks`` no-op tasks submitted and collected with
    ``as_completed`` on a LocalCluster: what the scheduler, the network and the client add to
    every task, the lower bound of a task's cost on Dask."""
    import time

    from distributed import Client, LocalCluster, as_completed

    with LocalCluster(n_workers=n_workers, threads_per_worker=1, host="127.0.0.1", dashboard_address="127.0.0.1:0") as cluster, Client(cluster) as client:
        client.gather(client.map(_noop, range(10)))  # warm up
        start = time.perf_counter()
        futures = client.map(_noop, range(tasks), pure=False)
        for _future, _value in as_completed(futures, with_results=True):  # as iter_fleet collects
            pass
        return (time.perf_counter() - start) / tasks


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m simgap.fleet.bench", description=__doc__.splitlines()[0])
    p.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    p.add_argument("--robots", type=int, default=6)
    p.add_argument("--days", type=int, default=5)
    p.add_argument("--overhead-tasks", type=int, default=1000, help="no-op tasks for the per-task overhead (0: skip)")
    args = p.parse_args(argv)

    import simgap
    from simgap import fleet
    from simgap.fleet.synthetic import make_synthetic_fleet

    with tempfile.TemporaryDirectory() as tmp:
        synthetic = make_synthetic_fleet(Path(tmp), robots=args.robots, days=args.days, with_step=True)
        index = fleet.index_from_folder(tmp)
        print(f"synthetic fleet: {args.robots} robots x {args.days} days, 3 logs of 2.5 s per robot-day (paper arm); simgap {simgap.__version__}, {platform.machine()}, {os.cpu_count()} logical cores")
        print()
        print("| workers | robot-days | wall [s] | diagnoses/min | diagnoses per core-minute (wall × workers) | task wall, median [s] | task CPU, median [s] | diagnoses per CPU-minute | worker RSS at task start [MiB] | peak increase per task, median / max [MiB] | load average before |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for workers in args.workers:
            load = " ".join(f"{x:.1f}" for x in os.getloadavg())
            result = fleet.diagnose_fleet(index, synthetic.urdf, n_workers=workers)
            t = result.tasks[result.tasks["status"] == "ok"]
            n = len(t)
            wall = result.wall_seconds
            increase = (t["peak_rss_mb"] - t["rss_start_mb"]).to_numpy()
            print(
                f"| {workers} | {n} | {wall:.1f} | {60 * n / wall:.1f} | {60 * n / (wall * workers):.1f} | {np.median(t['seconds']):.2f} | {np.median(t['cpu_seconds']):.2f} | {60 * n / t['cpu_seconds'].sum():.0f} "
                f"| {np.median(t['rss_start_mb']):.0f} | {np.median(increase):.0f} / {np.max(increase):.0f} | {load} |",
                flush=True,
            )
    if args.overhead_tasks:
        per_task = scheduler_overhead(max(args.workers), args.overhead_tasks)
        print(f"\nDask overhead: {args.overhead_tasks} no-op tasks on {max(args.workers)} workers, submitted and collected with as_completed: {1e3 * per_task:.2f} ms per task")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
