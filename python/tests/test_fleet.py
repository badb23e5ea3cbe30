"""simgap.fleet without a cluster: the fleet index and its held-out rule, reading a log with its
experiment sidecar on a worker, table rows read defensively from a report, the trend test and
the fleet's robust outlier score."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

pd = pytest.importorskip("pandas")

import simgap  # noqa: E402
from simgap import fleet  # noqa: E402
from simgap.fleet.run import _read  # noqa: E402


def touch(path: Path, text: str = "") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def test_folder_index_holds_out_the_last_log_of_each_robot_day(tmp_path: Path) -> None:
    touch(tmp_path / "arm.urdf")
    touch(tmp_path / "r1" / "2026-01-01" / "b.mcap")
    touch(tmp_path / "r1" / "2026-01-01" / "a.csv.gz")
    touch(tmp_path / "r1" / "2026-01-01" / "a.experiment.json", "{}")  # a sidecar, not a log
    touch(tmp_path / "r1" / "2026-01-01" / "notes.txt")
    touch(tmp_path / "r1" / "2026-01-01" / "sub" / "c.csv")
    touch(tmp_path / "r1" / "2026-01-02" / "bag" / "metadata.yaml")
    touch(tmp_path / "r1" / "2026-01-02" / "bag" / "bag_0.mcap")  # inside the bag: not a log of its own
    touch(tmp_path / "r1" / "2026-01-02" / "a.mcap")
    touch(tmp_path / "r2" / "2026-01-01" / "only.mcap")
    index = fleet.index_from_folder(tmp_path)
    rows = [(r.robot, r.day, Path(r.path).relative_to(tmp_path).as_posix(), r.role) for r in index.itertuples()]
    assert rows == [
        ("r1", "2026-01-01", "r1/2026-01-01/a.csv.gz", "fit"),
        ("r1", "2026-01-01", "r1/2026-01-01/b.mcap", "fit"),
        ("r1", "2026-01-01", "r1/2026-01-01/sub/c.csv", "holdout"),
        ("r1", "2026-01-02", "r1/2026-01-02/a.mcap", "fit"),
        ("r1", "2026-01-02", "r1/2026-01-02/bag", "holdout"),
        ("r2", "2026-01-01", "r2/2026-01-01/only.mcap", "holdout"),
    ]
    tasks = fleet.tasks_from_index(index)
    assert [(t.robot, t.day, len(t.fit), len(t.holdout)) for t in tasks] == [("r1", "2026-01-01", 2, 1), ("r1", "2026-01-02", 1, 1), ("r2", "2026-01-01", 0, 1)]
    assert tasks[0].problem() is None and "at least two logs" in (tasks[2].problem() or "")


def test_table_index_keeps_given_roles_and_rejects_partial_ones() -> None:
    given = fleet.index_from_table([
        {"robot": "r", "day": "d", "path": "z.mcap", "role": "fit"},
        {"robot": "r", "day": "d", "path": "a.mcap", "role": "holdout"},
        {"robot": "s", "day": "d", "path": "a.mcap"},
        {"robot": "s", "day": "d", "path": "b.mcap"},
    ])  # fmt: skip
    assert list(given["role"]) == ["holdout", "fit", "fit", "holdout"]
    with pytest.raises(ValueError, match="some logs have a role"):
        fleet.index_from_table([{"robot": "r", "day": "d", "path": "a", "role": "fit"}, {"robot": "r", "day": "d", "path": "b", "role": ""}])
    with pytest.raises(ValueError, match="unknown role"):
        fleet.index_from_table([{"robot": "r", "day": "d", "path": "a", "role": "train"}])
    with pytest.raises(ValueError, match="missing column"):
        fleet.index_from_table([{"robot": "r", "path": "a"}])
    with pytest.raises(FileNotFoundError):
        fleet.index_from_folder("/nonexistent/fleet")


def test_worker_reads_the_experiment_sidecar_of_a_log_that_has_none(tmp_path: Path) -> None:
    arm = simgap.Model.paper_arm()
    run = simgap.simulate(arm, [0.3, 0.5], controller="pd", kp=[64.72, 32.36], kv=[48.54, 6.472], duration=0.5)
    bare = simgap.Run(run.joints, run.t, run.q, run.qd, tau=run.tau, q_ref=run.q_ref, qd_ref=run.qd_ref)
    simgap.write_log(bare, tmp_path / "log.mcap")
    assert simgap.read_log(tmp_path / "log.mcap").experiment is None
    experiment = {"controller": "pd", "joints": "shoulder,elbow", "kp": "64.72,32.36", "kv": "48.54,6.472", "sample_period": "0.0025"}
    (tmp_path / "log.experiment.json").write_text(json.dumps(experiment))
    got = _read(str(tmp_path / "log.mcap"), arm.joint_names, {})
    assert got.experiment is not None and got.experiment["controller"] == "pd" and got.experiment["kp"] == "64.72,32.36"
    np.testing.assert_allclose(got.q, run.q, atol=1e-5)
    (tmp_path / "log.experiment.json").write_text("[1, 2]")
    with pytest.raises(simgap.LogError, match="experiment"):
        _read(str(tmp_path / "log.mcap"), arm.joint_names, {})


def test_diagnose_task_records_a_data_error_instead_of_raising(tmp_path: Path) -> None:
    urdf = Path(__file__).resolve().parents[2] / "crates" / "simgap-core" / "models" / "paper_arm.urdf"
    bad = touch(tmp_path / "bad.mcap", "not an mcap file")
    out = fleet.diagnose_task({"robot": "r", "day": "d", "fit": [str(bad)], "holdout": [str(bad)]}, str(urdf))
    assert out["status"] == "error" and out["error"].startswith(("LogError", "FitError")) and out["report"] is None
    assert out["seconds"] >= 0 and out["worker"]


REPORT = {
    "selected_effects": [
        {"effect": "coulomb_friction", "joints": ["shoulder", "elbow"], "parameters": {"fc": [7.1, 1.7]}, "uncertainty": {"fc": [0.1, 0.02]}, "units": {"fc": "N·m"}},
        {"effect": "payload", "joints": [], "parameters": {"mass": 1.5, "com": [0.0, 0.0, -0.45]}, "uncertainty": {"mass": 0.01}},
        {"effect": "inertial_error", "joints": ["elbow"], "parameters": {"delta_mass": [0.2], "delta_com": [[0.0, 0.0, 0.01]]}, "uncertainty": {}},
    ],
    "gap": {"holdout_l2_before": 0.08, "holdout_l2_after": 0.002, "kstep": {"horizons_s": [0.1, 0.5, 1.0], "before": [0.01, 0.05, 0.1], "after": [0.001, 0.004, None], "floor": [0.02, 0.3, 1.0]}},
}  # fmt: skip


def test_report_rows_one_per_effect_joint_and_parameter() -> None:
    rows = pd.DataFrame(fleet.report_rows("r", "d", REPORT))
    assert list(rows.columns) == fleet.TABLE_COLUMNS
    got = {(r.effect, r.joint, r.parameter): (r.value, r.uncertainty, r.unit) for r in rows.itertuples()}
    assert got[("coulomb_friction", "elbow", "fc")] == (1.7, 0.02, "N·m")
    assert got[("payload", "", "mass")] == (1.5, 0.01, "kg")
    assert got[("payload", "", "com[2]")][0] == -0.45 and math.isnan(got[("payload", "", "com[2]")][1])
    assert got[("inertial_error", "elbow", "delta_com[2]")][0] == 0.01 and got[("inertial_error", "elbow", "delta_mass")][2] == "kg"
    assert len(rows) == 2 + 4 + 4
    # the k-step columns take the horizon nearest 0.5 s; the closed-loop L² is on every row
    assert set(rows["kstep_horizon_s"]) == {0.5} and set(rows["kstep_before"]) == {0.05} and set(rows["kstep_after"]) == {0.004}
    assert set(rows["l2_before"]) == {0.08} and set(rows["status"]) == {"ok"}


def test_report_rows_read_reports_without_kstep_and_failures() -> None:
    old = {"selected_effects": [], "gap": {"holdout_l2_before": 0.1, "holdout_l2_after": 0.1}}
    (row,) = fleet.report_rows("r", "d", old)
    assert row["effect"] is None and math.isnan(row["kstep_before"]) and math.isnan(row["kstep_after"]) and row["l2_before"] == 0.1
    (failed,) = fleet.report_rows("r", "d", None, "error", "LogError: bad")
    assert failed["status"] == "error" and failed["error"] == "LogError: bad" and math.isnan(failed["l2_before"])


def fleet_table(values: dict[str, list[float]], sigma: float = 0.01, effect: str = "coulomb_friction", joint: str = "elbow", parameter: str = "fc") -> pd.DataFrame:
    """A fleet table of one series: robot -> value per day (NaN = effect not selected)."""
    days = [f"2026-01-{d + 1:02d}" for d in range(len(next(iter(values.values()))))]
    rows = []
    for robot, series in values.items():
        for day, v in zip(days, series):
            row = {c: math.nan for c in fleet.TABLE_COLUMNS} | {"robot": robot, "day": day, "status": "ok", "error": ""}
            if math.isnan(v):
                rows.append(row | {"effect": None, "joint": None, "parameter": None, "unit": None})
            else:
                rows.append(row | {"effect": effect, "joint": joint, "parameter": parameter, "value": v, "uncertainty": 1.96 * sigma, "unit": "N·m"})
    return pd.DataFrame(rows, columns=fleet.TABLE_COLUMNS)


def test_drift_flags_a_rising_parameter_and_not_noise() -> None:
    rng = np.random.default_rng(1)
    values = {f"r{i}": list(1.7 * (1 + 0.02 * i) + 0.01 * rng.standard_normal(5)) for i in range(5)}
    values["rising"] = [1.7 * (1 + 0.1 * d) for d in range(5)]
    dr = fleet.drift(fleet_table(values))
    assert set(dr.loc[dr["drifting"], "robot"]) == {"rising"}
    rising = dr.set_index("robot").loc["rising"]
    assert rising["slope_per_day"] == pytest.approx(0.17) and rising["days"] == 5
    # days are calendar days: a gap in the dates keeps the slope per day
    table = fleet_table({"r": [1.0, 1.1, 1.2]})
    table["day"] = table["day"].map({"2026-01-01": "2026-01-01", "2026-01-02": "2026-01-03", "2026-01-03": "2026-01-05"})
    assert fleet.drift(table)["slope_per_day"].iloc[0] == pytest.approx(0.05)


def test_drift_se_is_inflated_by_scatter_beyond_the_uncertainty() -> None:
    # a real slope of 2 %/day but scatter 20x the claimed sigma: not significant
    noisy = [1.0, 1.3, 0.95, 1.25, 1.08]
    dr = fleet.drift(fleet_table({"r": noisy}, sigma=0.001))
    assert dr["chi2_red"].iloc[0] > 100 and not dr["drifting"].iloc[0]


def test_outlier_scores_a_robot_that_alone_has_an_effect() -> None:
    nan = math.nan
    values = {f"r{i}": [nan, nan, nan] for i in range(5)}
    values["loaded"] = [nan, 1.5, 1.5]
    ol = fleet.outliers(fleet_table(values, effect="payload", joint="", parameter="mass"))
    flagged = ol[ol["outlier"]]
    assert set(flagged["robot"]) == {"loaded"} and list(flagged["day"]) == ["2026-01-02", "2026-01-03"]
    assert not ol.loc[ol["robot"] != "loaded", "present"].any()  # the others count at 0


def test_outlier_ignores_a_missing_selection_where_most_robots_have_the_effect() -> None:
    nan = math.nan
    values = {f"r{i}": [1.7 + 0.01 * i, 1.7] for i in range(5)}
    values["r0"] = [nan, 1.7]
    values["high"] = [1.71, 2.6]
    ol = fleet.outliers(fleet_table(values))
    assert ("r0", "2026-01-01") not in set(zip(ol["robot"], ol["day"]))
    assert set(zip(*ol.loc[ol["outlier"], ["robot", "day"]].T.values)) == {("high", "2026-01-02")}


def test_a_drifting_parameter_is_reported_as_drift_not_also_as_outlier() -> None:
    values = {f"r{i}": [1.7 * (1 + 0.01 * i)] * 5 for i in range(5)}
    values["rising"] = [1.7 * (1 + 0.1 * d) for d in range(5)]
    dr = fleet.drift(fleet_table(values))
    ol = fleet.outliers(fleet_table(values), drift_table=dr)
    assert ol.loc[ol["robot"] == "rising", "z"].max() > 4
    assert not ol["outlier"].any()
    flags = fleet.flagged_robots(dr, ol)
    assert list(zip(flags["robot"], flags["finding"], flags["since"])) == [("rising", "drift", "2026-01-01")]


def test_too_few_robots_give_no_outlier_score_and_empty_tables_keep_their_columns() -> None:
    table = fleet_table({"r1": [1.0, 1.0], "r2": [1.0, 2.0]})
    dr, ol = fleet.drift(table), fleet.outliers(table)
    assert ol.empty and list(ol.columns)[:2] == ["day", "robot"] and not dr["drifting"].any()
    flags = fleet.flagged_robots(dr, ol)
    assert flags.empty and "robot" in flags.columns


def test_progress_without_tqdm_is_a_ticking_line(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    from simgap.fleet.run import _progress

    monkeypatch.setitem(__import__("sys").modules, "tqdm.auto", None)  # as if not installed
    tick, close = _progress(2, True)
    tick({"robot": "r1", "day": "d1", "status": "ok"})
    tick({"robot": "r2", "day": "d1", "status": "error"})
    close()
    err = capsys.readouterr().err
    assert "fleet: 0/2" in err and "2/2 robot-days" in err and "r2 d1 error" in err


def test_fleet_result_tables_from_task_results() -> None:
    report = REPORT | {"gap": REPORT["gap"] | {"headline": "k_step"}}
    results = [
        {"robot": "r2", "day": "d1", "status": "ok", "error": "", "report": report, "seconds": 1.5, "cpu_seconds": 0.7, "rss_start_mb": 180.0, "peak_rss_mb": 190.0, "worker": "h:1"},
        {"robot": "r1", "day": "d1", "status": "error", "error": "LogError: bad", "report": None, "seconds": 0.1, "worker": "h:2"},
    ]
    result = fleet.FleetResult.from_results(results)
    assert list(result.tasks["robot"]) == ["r1", "r2"] and list(result.failed["error"]) == ["LogError: bad"]
    ok = result.tasks.iloc[1]
    assert ok["headline"] == "k_step" and ok["kstep_after"] == 0.004 and ok["effects"] == "coulomb_friction, payload, inertial_error"
    assert len(result.table) == 1 + 10 and list(result.reports) == [("r2", "d1")]
    assert "1/2 robot-days diagnosed" in repr(result)
