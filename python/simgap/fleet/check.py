"""The fleet checked against what was planted: ``python -m simgap.fleet.check [--workers 2]``.

Writes the second synthetic fleet (:func:`simgap.fleet.synthetic.make_change_fleet`: a
three-joint arm, four planted changes, clean robots, MCAP / gzipped CSV / bag folders),
diagnoses it on a LocalCluster, and prints

- the findings against the planted changes (found with the right kind and day, missed, and
  anything flagged that was not planted),
- the **interval coverage**: the fraction of the true parameters of every robot-day inside the
  reported 95 % intervals, per effect, with the median |error| / half-width (0.34 for
  calibrated Gaussian intervals: the median |z|, 0.674, over 1.96) and the factor by which the
  half-widths would have to be scaled for 95 % of the errors to fall inside (1 when calibrated,
  above 1 when they are too narrow, below 1 when too wide),
- the throughput: robot-days per core-minute (wall × workers) and per CPU-minute.

:func:`interval_coverage` is the measurement, usable on any fleet with a known truth.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from .trends import Z95

__all__ = ["interval_coverage", "main"]


def interval_coverage(table: pd.DataFrame, truth: dict[tuple[str, str], dict[tuple[str, str, str], float]]) -> pd.DataFrame:
    """One row per reported parameter that has a true value and a finite interval:
    ``robot, day, effect, joint, parameter, true, value, uncertainty, inside`` (the true value
    within value ± uncertainty, the report's 95 % half-width), ``z`` ((value − true) / σ,
    σ = half-width / 1.96). ``truth``: ``(robot, day) -> {(effect, joint, parameter): value}``
    (``joint`` '' for whole-robot parameters)."""
    rows = []
    ok = table[(table["status"] == "ok") & table["effect"].notna()]
    for r in ok.itertuples(index=False):
        true = truth.get((r.robot, r.day), {}).get((r.effect, r.joint or "", r.parameter))
        u = float(r.uncertainty)
        if true is None or not np.isfinite(u) or u <= 0:
            continue
        rows.append({"robot": r.robot, "day": r.day, "effect": r.effect, "joint": r.joint, "parameter": r.parameter, "true": true, "value": float(r.value), "uncertainty": u, "inside": bool(abs(r.value - true) <= u), "z": (r.value - true) / (u / Z95)})
    return pd.DataFrame(rows, columns=["robot", "day", "effect", "joint", "parameter", "true", "value", "uncertainty", "inside", "z"])


def variant_coverage(reports: dict[tuple[str, str], dict], truth: dict[tuple[str, str], dict[tuple[str, str, str], float]]) -> pd.DataFrame:
    """Coverage of each interval method on its own (the reports' ``interval_variants``, see
    :attr:`simgap.Report.interval_variants`) against the reported intervals, over the robot-days
    whose parameters were fitted on the torque residual: one row per method (``reported`` for
    the report's own) with ``n``, ``inside``, ``median_ratio`` and ``scale_for_95`` as in
    :func:`coverage_summary`."""
    from .result import report_rows

    tables: dict[str, list[dict]] = {}
    for (robot, day), report in sorted(reports.items()):
        variants = report.get("interval_variants") or {}
        if "resampling" not in variants:
            continue  # fitted by multiple shooting: its own variant only
        for name, effects in [("reported", report.get("selected_effects") or []), *variants.items()]:
            tables.setdefault(name, []).extend(report_rows(robot, day, {**report, "selected_effects": effects}))
    columns = ["n", "inside", "median_ratio", "scale_for_95"]
    rows = []
    for name, rws in tables.items():
        cov = interval_coverage(pd.DataFrame(rws), truth)
        if len(cov):
            rows.append({"method": name, **coverage_summary(cov).iloc[0][columns].to_dict()})  # the row of all parameters
    return pd.DataFrame(rows, columns=["method", *columns])


def coverage_summary(cov: pd.DataFrame) -> pd.DataFrame:
    """Per effect and parameter: ``n``, ``inside`` (fraction within the 95 % intervals),
    ``median_ratio`` (median |error| / half-width; 0.34 for calibrated Gaussian intervals) and
    ``scale_for_95`` (the factor the half-widths need for 95 % of the errors to fall inside:
    above 1 too narrow, below 1 too wide), ``bias`` (the median relative error, (value − true)
    / |true|) and ``z_mean``, ``z_std`` (of (value − true) / σ: 0 and 1 for unbiased,
    calibrated intervals)."""
    cov = cov.assign(ratio=(cov["value"] - cov["true"]).abs() / cov["uncertainty"], rel=(cov["value"] - cov["true"]) / cov["true"].abs())
    rows = []
    for key, g in [(("all", ""), cov), *cov.groupby(["effect", "parameter"], sort=True)]:
        rows.append({
            "effect": key[0], "parameter": key[1], "n": len(g), "inside": g["inside"].mean(), "median_ratio": g["ratio"].median(),
            "scale_for_95": float(np.quantile(g["ratio"], 0.95)) if len(g) else np.nan, "bias": g["rel"].median(), "z_mean": g["z"].mean(), "z_std": g["z"].std(),
        })  # fmt: skip
    return pd.DataFrame(rows)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m simgap.fleet.check", description=__doc__.splitlines()[0])
    p.add_argument("--workers", type=int, default=2, help="LocalCluster worker processes (default 2)")
    p.add_argument("--dir", type=Path, default=None, help="where to write the fleet (default: a temporary folder)")
    p.add_argument("--html", type=Path, default=None, help="also write the fleet report here")
    args = p.parse_args(argv)

    import simgap
    from simgap import fleet
    from simgap.fleet.synthetic import make_change_fleet

    with tempfile.TemporaryDirectory() as tmp:
        root = args.dir or Path(tmp)
        start = time.perf_counter()
        planted = make_change_fleet(root)
        print(f"wrote {len(planted.robots)} robots x {len(planted.days)} days of the three-joint arm in {time.perf_counter() - start:.0f} s ({', '.join(f'{r}: {f}' for r, f in planted.formats.items())})")
        load = " ".join(f"{x:.1f}" for x in os.getloadavg())
        result = fleet.diagnose_fleet(fleet.index_from_folder(root), planted.urdf, n_workers=args.workers, progress=True)
        flags = result.findings()
        got = {(r.robot, r.finding, r.effect, r.joint, r.parameter, r.since) for r in flags.itertuples()}
        want = {(x.robot, x.kind, x.effect, x.joint, x.parameter, x.since) for x in planted.planted}
        print(f"\n{int((result.tasks['status'] == 'ok').sum())} of {len(result.tasks)} robot-days diagnosed\n\nplanted changes:")
        for x in planted.planted:
            mark = "found" if (x.robot, x.kind, x.effect, x.joint, x.parameter, x.since) in got else "MISSED"
            print(f"  {mark:6s} {x.robot} {x.kind} {x.effect} {x.joint or '-'} {x.parameter} since {x.since}")
        extra = sorted(got - want)
        print(f"flagged but not planted: {len(extra)}" + "".join(f"\n  {e}" for e in extra))
        print(f"clean robots flagged: {sorted(set(flags['robot']) & set(planted.clean))}")
        print()
        with pd.option_context("display.width", 250, "display.max_colwidth", 200):
            for r in flags.itertuples(index=False):
                alt = f" [also: {r.alternatives}]" if r.alternatives else ""
                print(f"  {r.robot} {r.finding} ({r.test}): {r.detail}{alt}")
            cov = interval_coverage(result.table, planted.truth)
            print("\ninterval coverage of the true parameters (reported 95 % intervals), per effect and per joint:")
            print(coverage_summary(cov).to_string(index=False, float_format=lambda v: f"{v:.3g}"))
            per_joint = cov.groupby(["effect", "joint", "parameter"], sort=True).agg(n=("inside", "size"), inside=("inside", "mean"), z_mean=("z", "mean"), z_std=("z", "std"))
            print(per_joint.to_string(float_format=lambda v: f"{v:.3g}"))
            print("\neach interval method on its own (robot-days fitted on the torque residual):")
            print(variant_coverage(result.reports, planted.truth).to_string(index=False, float_format=lambda v: f"{v:.3g}"))
        t = result.tasks[result.tasks["status"] == "ok"]
        n, wall = len(t), result.wall_seconds
        print(
            f"\nthroughput: {n} robot-days in {wall:.1f} s on {result.workers} workers: {60 * n / (wall * result.workers):.1f} robot-days per core-minute (wall x workers), "
            f"{60 * n / t['cpu_seconds'].sum():.1f} per CPU-minute (median task {np.median(t['cpu_seconds']):.2f} CPU-s); load average before {load}; "
            f"simgap {simgap.__version__}, {platform.machine()}, {os.cpu_count()} logical cores"
        )
        if args.html:
            result.to_html(args.html)
    return 0 if want <= got and not (got - want) else 1


if __name__ == "__main__":
    raise SystemExit(main())
