"""``python -m simgap.fleet DIR --urdf ROBOT.urdf [--scheduler tcp://HOST:PORT] [--out OUT/]``

Diagnoses every robot-day of the folder ``DIR/ROBOT/DAY/…`` on a Dask cluster (a LocalCluster
of this machine's cores unless ``--scheduler`` names one) with a progress bar, prints the
flagged robots and writes into ``OUT/``:

- ``fleet.parquet``: one row per robot, day, effect, joint, parameter (``fleet.csv`` when
  pyarrow is missing),
- ``tasks.csv``: one row per robot-day (status, error, gap figures, seconds, peak memory),
- ``drift.csv``, ``outliers.csv``, ``flagged.csv``: the trend tests, the robust z scores and
  the findings,
- ``fleet.html``: the fleet report,
- ``reports/ROBOT/DAY.json``: each robot-day's diagnosis report.

They are written in that order, the table first and the HTML report last; an output that
cannot be written (e.g. matplotlib missing for the report) is named on stderr, the others are
written, and the exit status is 1.

Outputs are written to a temporary folder and moved into ``OUT/`` at the end, so an
interrupted run (Ctrl-C: exit status 130) leaves them complete or absent. Exit status 0 when
at least one robot-day was diagnosed and every output was written, 1 when none was diagnosed
or an output could not be written, 2 for bad arguments or an unreachable scheduler.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from simgap._simgap import DIAGNOSE_SWITCHES

if TYPE_CHECKING:
    from .findings import Findings
    from .result import FleetResult


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m simgap.fleet", description="Diagnose every robot of a fleet on every day, on a Dask cluster, and flag drifting and outlying robots.")
    p.add_argument("folder", type=Path, help="fleet folder laid out as ROBOT/DAY/<logs> (.mcap, .csv, .csv.gz, bag folders, LeRobot datasets: one log per episode)")
    p.add_argument("--urdf", type=Path, required=True, help="the robots' URDF (a path every worker can read)")
    p.add_argument("--tip", default=None, help="tip link of the chain (default: the end of the unique chain)")
    p.add_argument("--calibration", type=Path, default=None, help="LeRobot's calibration file (a path every worker can read): makes a dataset's range-normalised gripper an angle")
    p.add_argument("--scheduler", default=None, help="Dask scheduler address, e.g. tcp://scheduler-host:8786 (default: a LocalCluster on this machine)")
    p.add_argument("--workers", type=int, default=None, help="LocalCluster worker processes (default: the number of cores)")
    p.add_argument("--out", type=Path, default=Path("fleet-out"), help="output folder (default: fleet-out)")
    p.add_argument("--formulation", default="euler_lagrange", choices=["euler_lagrange", "euler-lagrange", "simplified"])
    # the diagnosis' switches, as simgap diagnose has them (one table: DIAGNOSE_SWITCHES)
    for name, _default, help in DIAGNOSE_SWITCHES:
        p.add_argument("--" + name.replace("_", "-"), action="store_true", help=help)
    p.add_argument("--retries", type=int, default=2, help="re-runs of a task that fails for a reason other than its data (default 2)")
    p.add_argument("--z-drift", type=float, default=4.0, help="drift and step: z threshold of the change tests (default 4)")
    p.add_argument("--min-rate", type=float, default=0.02, help="drift: minimum relative rate per day (default 0.02)")
    p.add_argument("--min-step", type=float, default=0.10, help="step: minimum relative step (default 0.10)")
    p.add_argument("--z-outlier", type=float, default=4.0, help="outlier (against the fleet) and effect (against neutral): z threshold (default 4)")
    p.add_argument("--min-flagged-days", type=int, default=2, help="outlier / effect: days a robot must be flagged on to be reported (default 2)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


def _thresholds(args: argparse.Namespace) -> dict[str, float]:
    return {"z_drift": args.z_drift, "min_rate_per_day": args.min_rate, "min_step": args.min_step, "z_outlier": args.z_outlier, "min_flagged_days": args.min_flagged_days}


def _write(result: FleetResult, findings: Findings, folder: Path, args: argparse.Namespace) -> list[str]:
    """Writes every output into ``folder``, the table first and the HTML report last; one that
    fails (a missing module, a full disk) is named in the returned list and the others are
    still written."""
    from .report import write_html

    def table() -> None:
        try:
            result.to_parquet(folder / "fleet.parquet")
        except ImportError:
            print("simgap.fleet: pyarrow is not installed; writing fleet.csv instead of fleet.parquet", file=sys.stderr)
            result.table.to_csv(folder / "fleet.csv", index=False)

    def reports() -> None:
        for (robot, day), report in result.reports.items():
            path = folder / "reports" / robot / f"{day}.json"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(report, indent=1))

    steps = [
        ("fleet.parquet", table),
        ("tasks.csv", lambda: result.tasks.to_csv(folder / "tasks.csv", index=False)),
        ("drift.csv", lambda: findings.drift.to_csv(folder / "drift.csv", index=False)),
        ("outliers.csv", lambda: findings.outliers.to_csv(folder / "outliers.csv", index=False)),
        ("flagged.csv", lambda: findings.flags.to_csv(folder / "flagged.csv", index=False)),
        ("reports/", reports),
        ("fleet.html", lambda: write_html(result, folder / "fleet.html", findings=findings, title=args.folder.resolve().name, **_thresholds(args))),
    ]
    failed = []
    for name, write in steps:
        try:
            write()
        except ImportError as err:
            print(f"simgap.fleet: could not write {name}: {err.name or err} is not installed (the fleet extra installs it: pip install \"simgap[fleet]\")", file=sys.stderr)
            failed.append(name)
        except (OSError, ValueError, TypeError, KeyError, RuntimeError) as err:
            print(f"simgap.fleet: could not write {name}: {type(err).__name__}: {err}", file=sys.stderr)
            failed.append(name)
        if name in failed and not name.endswith("/"):
            (folder / name).unlink(missing_ok=True)  # no half-written file
    return failed


def _move_into(tmp: Path, out: Path) -> None:
    """Moves the finished outputs into ``out`` with Ctrl-C held back, so they land whole."""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        if not out.exists():
            os.rename(tmp, out)
            return
        for entry in tmp.iterdir():
            dest = out / entry.name
            if dest.is_dir() and not dest.is_symlink():
                shutil.rmtree(dest)
            os.replace(entry, dest)
        tmp.rmdir()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    from .index import index_from_folder
    from .findings import find
    from .report import summary_text
    from .run import diagnose_fleet

    if not args.urdf.is_file():
        print(f"simgap.fleet: URDF {args.urdf} not found", file=sys.stderr)
        return 2
    try:
        index = index_from_folder(args.folder)
    except (FileNotFoundError, ValueError) as err:
        print(f"simgap.fleet: {err}", file=sys.stderr)
        return 2
    out = args.out.resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    client = None
    # Ctrl-C is remembered as well as raised: code between here and the outputs that catches
    # the KeyboardInterrupt (a library's wait loop, a generator's cleanup) cannot turn an
    # interrupted run into a finished one
    interrupted: list[bool] = []

    def on_sigint(signum: int, frame: object) -> None:
        interrupted.append(True)
        raise KeyboardInterrupt

    def check_interrupted() -> None:
        if interrupted:
            raise KeyboardInterrupt

    previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        if args.scheduler:
            from distributed import Client

            try:
                client = Client(args.scheduler, timeout="30s")
            except (OSError, TimeoutError, ValueError) as err:
                print(f"simgap.fleet: cannot reach the scheduler {args.scheduler}: {err}", file=sys.stderr)
                return 2
        options = {name: getattr(args, name) for name, _default, _help in DIAGNOSE_SWITCHES}
        result = diagnose_fleet(
            index,
            args.urdf,
            client,
            tip=args.tip,
            formulation=args.formulation,
            retries=args.retries,
            progress=not args.no_progress,
            n_workers=args.workers,
            diagnose_options=options,
            read_options={"calibration": str(args.calibration)} if args.calibration else None,
        )
        check_interrupted()
        findings = find(result.table, result.reports, **_thresholds(args))
        print(summary_text(result, findings))
        failed = _write(result, findings, tmp, args)
        check_interrupted()
        _move_into(tmp, out)
        written = [n for n in ("fleet.parquet", "fleet.csv", "tasks.csv", "drift.csv", "outliers.csv", "flagged.csv", "fleet.html", "reports") if (out / n).exists()]
        print(f"wrote {out}/ ({', '.join(written)})")
        if failed:
            print(f"simgap.fleet: not written: {', '.join(failed)}", file=sys.stderr)
            return 1
        return 0 if (result.tasks["status"] == "ok").any() else 1
    except KeyboardInterrupt:
        print("\nsimgap.fleet: interrupted; no output written", file=sys.stderr)
        return 130
    finally:
        if previous is not None:  # None: a handler not installed from Python, which cannot be restored
            signal.signal(signal.SIGINT, previous)
        shutil.rmtree(tmp, ignore_errors=True)
        if client is not None:
            client.close()


if __name__ == "__main__":
    sys.exit(main())
