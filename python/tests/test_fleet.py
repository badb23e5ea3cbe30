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


def test_diagnose_task_passes_its_diagnose_options(tmp_path: Path) -> None:
    # a robot-day of the paper's arm: told that the effort is a link-side sensor's, the task's
    # diagnosis tries no rotor inertia and says so; without it, it does try one
    arm = simgap.Model.paper_arm()
    paths = []
    for i, target in enumerate(([0.6, 1.0], [-0.5, 0.8])):
        run = simgap.simulate(arm, target, controller="pd_gravity", kp=[64.72, 32.36], kv=[48.54, 6.472], effects=["viscous_friction:b=0.5,0.2"], duration=3.0)
        paths.append(str(tmp_path / f"run{i}.mcap"))
        simgap.write_log(run, paths[-1])
    urdf = str(Path(__file__).resolve().parents[2] / "crates" / "simgap-core" / "models" / "paper_arm.urdf")
    task = {"robot": "r", "day": "d", "fit": paths[:1], "holdout": paths[1:]}
    told = fleet.diagnose_task(task, urdf, diagnose_options={"link_side_torque": True})
    assert told["status"] == "ok", told["error"]
    assert "armature" not in [c["effect"] for c in told["report"]["candidates"]]
    assert any("link side of the gearbox" in n for n in told["report"]["notes"])
    default = fleet.diagnose_task(task, urdf)
    assert "armature" in [c["effect"] for c in default["report"]["candidates"]]


REPORT = {
    "selected_effects": [
        {"effect": "coulomb_friction", "joints": ["shoulder", "elbow"], "parameters": {"fc": [7.1, 1.7]}, "uncertainty": {"fc": [0.1, 0.02]}, "units": {"fc": "N·m"}},
        {"effect": "payload", "joints": [], "parameters": {"mass": 1.5, "com": [0.0, 0.0, -0.45]}, "uncertainty": {"mass": 0.01}},
        {"effect": "inertial_error", "joints": ["elbow"], "parameters": {"delta_mass": [0.2], "delta_com": [[0.0, 0.0, 0.01]], "identifiable_directions": 3}, "uncertainty": {}},
    ],
    "gap": {"holdout_l2_before": 0.08, "holdout_l2_after": 0.002, "kstep": {"horizons_s": [0.1, 0.5, 1.0], "before": [0.01, 0.05, 0.1], "after": [0.001, 0.004, None], "floor": [0.02, 0.3, 1.0]}},
    "alternatives": [{"effects": ["coulomb_friction", "inertial_error"], "why": "a payload and an inertial error of the last link are the same dynamics"}],
}  # fmt: skip


def test_report_rows_one_per_effect_joint_and_parameter_and_never_a_count() -> None:
    rows = pd.DataFrame(fleet.report_rows("r", "d", REPORT))
    assert list(rows.columns) == fleet.TABLE_COLUMNS
    got = {(r.effect, r.joint, r.parameter): (r.value, r.uncertainty, r.unit, r.identified) for r in rows.itertuples()}
    assert got[("coulomb_friction", "elbow", "fc")] == (1.7, 0.02, "N·m", True)
    assert got[("payload", "", "mass")] == (1.5, 0.01, "kg", True)
    # the centre of mass comes without an interval: a row, but not an identified parameter
    assert got[("payload", "", "com[2]")][0] == -0.45 and math.isnan(got[("payload", "", "com[2]")][1]) and not got[("payload", "", "com[2]")][3]
    assert got[("inertial_error", "elbow", "delta_com[2]")][0] == 0.01 and got[("inertial_error", "elbow", "delta_mass")][2] == "kg"
    assert not any("identifiable_directions" in p for p in rows["parameter"])  # a count is no row
    assert len(rows) == 2 + 4 + 4
    # the k-step columns take the horizon nearest 0.5 s; the closed-loop L² is on every row
    assert set(rows["kstep_horizon_s"]) == {0.5} and set(rows["kstep_before"]) == {0.05} and set(rows["kstep_after"]) == {0.004}
    assert set(rows["l2_before"]) == {0.08} and set(rows["status"]) == {"ok"}


def test_units_follow_the_joint_type() -> None:
    report = {"selected_effects": [{"effect": "viscous_friction", "joints": ["slide", "hinge"], "parameters": {"b": [3.0, 0.2]}, "uncertainty": {"b": [0.1, 0.01]}, "units": {"b": "N·m·s/rad"}}]}
    rows = fleet.report_rows("r", "d", report, joint_types={"slide": "prismatic", "hinge": "revolute"})
    assert [(r["joint"], r["joint_type"], r["unit"]) for r in rows] == [("slide", "prismatic", "N·s/m"), ("hinge", "revolute", "N·m·s/rad")]
    assert fleet.unit("coulomb_friction", "fc", "prismatic") == "N" and fleet.unit("armature", "ia", "prismatic") == "kg"
    assert fleet.unit("payload", "com[1]", "") == "m" and fleet.unit("torque_gain", "k") == "-"
    with pytest.raises(ValueError, match="joint type"):
        fleet.unit("viscous_friction", "b", "spherical")


def test_vocabulary_neutral_values_and_non_parameters() -> None:
    assert fleet.neutral("torque_gain", "k") == 1.0 and fleet.neutral("viscous_friction", "b") == 0.0
    assert fleet.neutral("payload", "com[2]") is None and fleet.neutral("torque_saturation", "limit") is None
    assert not fleet.is_parameter("inertial_error", "identifiable_directions") and not fleet.is_parameter("cogging", "periods_per_rev")
    assert not fleet.is_parameter("coulomb_friction", "w") and fleet.is_parameter("coulomb_friction", "fc")
    assert fleet.min_change("payload", "mass") > 1e-6 and fleet.min_change("inertial_error", "delta_inertia[0]") > 1e-12


def test_report_rows_read_reports_without_kstep_and_failures() -> None:
    old = {"selected_effects": [], "gap": {"holdout_l2_before": 0.1, "holdout_l2_after": 0.1}}
    (row,) = fleet.report_rows("r", "d", old)
    assert row["effect"] is None and math.isnan(row["kstep_before"]) and math.isnan(row["kstep_after"]) and row["l2_before"] == 0.1
    (failed,) = fleet.report_rows("r", "d", None, "error", "LogError: bad")
    assert failed["status"] == "error" and failed["error"] == "LogError: bad" and math.isnan(failed["l2_before"])


def fleet_table(values: dict[str, list[float]], sigma: float | dict[str, list[float]] = 0.01, effect: str = "coulomb_friction", joint: str = "elbow", parameter: str = "fc", unit: str = "N·m") -> pd.DataFrame:
    """A fleet table of one series: robot -> value per day (NaN = effect not selected); ``sigma``
    one standard deviation for all, or robot -> per day."""
    days = [f"2026-01-{d + 1:02d}" for d in range(len(next(iter(values.values()))))]
    rows = []
    for robot, series in values.items():
        for i, (day, v) in enumerate(zip(days, series)):
            row = {c: math.nan for c in fleet.TABLE_COLUMNS} | {"robot": robot, "day": day, "status": "ok", "error": ""}
            if math.isnan(v):
                rows.append(row | {"effect": None, "joint": None, "joint_type": None, "parameter": None, "unit": None, "identified": False})
            else:
                s = sigma[robot][i] if isinstance(sigma, dict) else sigma
                rows.append(row | {"effect": effect, "joint": joint, "joint_type": "revolute" if joint else "", "parameter": parameter, "value": v, "uncertainty": 1.96 * s, "unit": unit, "identified": True})
    return pd.DataFrame(rows, columns=fleet.TABLE_COLUMNS)


def noisy_fleet(rng: np.random.Generator, days: int, level: float, noise: float, wide: float) -> tuple[dict[str, list[float]], dict[str, list[float]]]:
    """Six robots whose values scatter by ``noise`` (relative) about their own level, reported
    with intervals ``wide`` times too wide."""
    values, sigmas = {}, {}
    for i in range(6):
        own = level * (1 + 0.03 * rng.standard_normal())
        values[f"r{i}"] = list(own * (1 + noise * rng.standard_normal(days)))
        sigmas[f"r{i}"] = [wide * noise * own] * days
    return values, sigmas


def test_a_drift_is_found_with_intervals_too_wide_and_noise_is_not() -> None:
    # 95 % half-widths of ±25 % on a 3 % scatter (the diagnosis's were ±20–35 %): scaled on the fleet, both ways
    rng = np.random.default_rng(3)
    values, sigmas = noisy_fleet(rng, 6, 1.78, 0.03, 4.2)
    values["r0"] = [1.78 * 1.08**d * (1 + 0.03 * e) for d, e in enumerate(rng.standard_normal(6))]
    dr = fleet.drift(fleet_table(values, sigmas, "viscous_friction", "shoulder", "b", "N·m·s/rad")).set_index("robot")
    assert list(dr.index[dr["drifting"]]) == ["r0"] and dr.at["r0", "change"] == "trend"
    assert 0.05 < dr.at["r0", "rate_per_day"] < 0.12 and dr.at["r0", "scale"] < 0.6  # the intervals were shrunk
    # the weighted test of before (standard error only ever inflated) would not have found it
    w_se = np.sqrt(1 / np.sum((np.arange(6) - 2.5) ** 2 / (np.array(sigmas["r0"]) ** 2)))
    assert dr.at["r0", "slope_per_day"] / w_se < 4 < dr.at["r0", "z"]


def test_scatter_beyond_the_fleets_is_no_drift() -> None:
    # a robot whose own scatter is 20x its intervals, with a slope of 2 %/day: not significant
    rng = np.random.default_rng(4)
    values, sigmas = noisy_fleet(rng, 5, 1.0, 0.01, 1.0)
    values["r0"] = [1.0, 1.3, 0.95, 1.25, 1.08]
    dr = fleet.drift(fleet_table(values, sigmas)).set_index("robot")
    assert dr.at["r0", "chi2_red"] > 100 and not dr["drifting"].any()
    # alone (no fleet to calibrate on), its own scatter sets the scale: still not significant
    assert not fleet.drift(fleet_table({"r0": values["r0"]}, 0.001))["drifting"].any()


def test_a_step_is_told_from_a_trend_and_dated() -> None:
    rng = np.random.default_rng(5)
    values, sigmas = noisy_fleet(rng, 6, 0.9, 0.03, 2.0)
    values["r1"] = [0.9 * (1.6 if d >= 3 else 1.0) * (1 + 0.03 * e) for d, e in enumerate(rng.standard_normal(6))]
    values["r2"] = [0.9 * (1 + 0.1 * d) for d in range(6)]
    dr = fleet.drift(fleet_table(values, sigmas)).set_index("robot")
    assert set(dr.index[dr["drifting"]]) == {"r1", "r2"}
    assert dr.at["r1", "change"] == "step" and dr.at["r1", "step_day"] == "2026-01-04" and dr.at["r1", "step_ratio"] == pytest.approx(1.6, rel=0.08)
    assert dr.at["r2", "change"] == "trend"
    flags = fleet.flagged_robots(dr.reset_index(), fleet.outliers(fleet_table(values, sigmas), drift_table=dr.reset_index()))
    got = {(r.robot, r.finding, r.since) for r in flags.itertuples()}
    assert got == {("r1", "step", "2026-01-04"), ("r2", "drift", "2026-01-01")}
    step = flags.set_index("robot").loc["r1", "detail"]
    assert step.startswith("since 2026-01-04, a step of ×1.")


def test_an_effect_one_robot_has_is_judged_against_neutral_with_its_own_interval() -> None:
    # a torque gain of 0.895 ± 0.004 on one robot from day 2: 10 % from neutral, 50 of its sigmas
    nan = math.nan
    values = {f"r{i}": [nan] * 5 for i in range(5)}
    values["weak"] = [nan, 0.895, 0.892, 0.898, 0.894]
    table = fleet_table(values, 0.004 / 1.96, "torque_gain", "elbow", "k", "–")
    ol = fleet.outliers(table)
    flagged = ol[ol["outlier"]]
    assert set(flagged["robot"]) == {"weak"} and list(flagged["day"]) == ["2026-01-02", "2026-01-03", "2026-01-04", "2026-01-05"]
    assert set(flagged["reference"]) == {"neutral"} and (flagged["median"] == 1.0).all() and (flagged["z"] < -40).all()
    flags = fleet.flagged_robots(fleet.drift(table), ol)
    assert list(zip(flags["robot"], flags["finding"], flags["since"], flags["test"])) == [("weak", "effect", "2026-01-02", "neutral")]
    # a gain as far from 1 but with an interval that includes 1 is no finding
    values["weak"] = [nan, 0.895, 0.892, 0.898, 0.894]
    assert not fleet.outliers(fleet_table(values, 0.06, "torque_gain", "elbow", "k", "–"))["outlier"].any()


def test_zeros_and_missing_intervals_raise_no_alarm() -> None:
    # a robot-day's inertial correction of 9e-9 kg: with no interval it is not tested at all,
    # with a tiny one it is below the unit's minimum change
    nan = math.nan
    values = {f"r{i}": [nan, nan, nan] for i in range(5)}
    values["odd"] = [nan, 9e-9, nan]
    assert fleet.outliers(fleet_table(values, nan, "inertial_error", "elbow", "delta_mass", "kg")).empty
    ol = fleet.outliers(fleet_table(values, 1e-12, "inertial_error", "elbow", "delta_mass", "kg"))
    assert len(ol[ol["present"]]) == 1 and abs(ol.loc[ol["present"], "z"].iloc[0]) > 1e3 and not ol["outlier"].any()
    # a fleet with the effect at zero: the spread floor is the unit's minimum, not 0
    values = {f"r{i}": [0.0, 0.0, 0.0] for i in range(5)} | {"odd": [0.0, 1e-6, 0.0]}
    ol = fleet.outliers(fleet_table(values, 1e-9, "torque_offset", "elbow", "offset"))
    assert np.isfinite(ol["z"]).all() and (ol["spread"] >= fleet.min_change("torque_offset", "offset")).all() and not ol["outlier"].any()
    # an unresolved coordinate (no interval) never makes a trend either
    assert fleet.drift(fleet_table({"r": [0.0, -0.1, -0.2]}, nan, "payload", "", "com[1]", "m")).empty


def test_outlier_scores_a_robot_that_alone_has_an_effect() -> None:
    nan = math.nan
    values = {f"r{i}": [nan, nan, nan] for i in range(5)}
    values["loaded"] = [nan, 1.5, 1.5]
    ol = fleet.outliers(fleet_table(values, effect="payload", joint="", parameter="mass", unit="kg"))
    flagged = ol[ol["outlier"]]
    assert set(flagged["robot"]) == {"loaded"} and list(flagged["day"]) == ["2026-01-02", "2026-01-03"]
    assert not ol.loc[ol["robot"] != "loaded", "present"].any()  # the others sit at 0, not scored
    assert ol.loc[ol["robot"] != "loaded", "z"].isna().all()


def test_outlier_ignores_a_missing_selection_where_most_robots_have_the_effect() -> None:
    nan = math.nan
    values = {f"r{i}": [1.7 + 0.01 * i, 1.7] for i in range(5)}
    values["r0"] = [nan, 1.7]
    values["high"] = [1.71, 2.6]
    ol = fleet.outliers(fleet_table(values))
    assert ("r0", "2026-01-01") not in set(zip(ol["robot"], ol["day"]))
    assert set(zip(*ol.loc[ol["outlier"], ["robot", "day"]].T.values)) == {("high", "2026-01-02")}
    assert set(ol["reference"]) == {"fleet"}


def test_a_drifting_parameter_is_reported_as_drift_not_also_as_outlier() -> None:
    values = {f"r{i}": [1.7 * (1 + 0.01 * i)] * 5 for i in range(5)}
    values["rising"] = [1.7 * (1 + 0.1 * d) for d in range(5)]
    dr = fleet.drift(fleet_table(values))
    ol = fleet.outliers(fleet_table(values), drift_table=dr)
    assert ol.loc[ol["robot"] == "rising", "z"].max() > 4
    assert not ol["outlier"].any()
    flags = fleet.flagged_robots(dr, ol)
    assert list(zip(flags["robot"], flags["finding"], flags["since"])) == [("rising", "drift", "2026-01-01")]


def test_days_are_calendar_days() -> None:
    # a gap in the dates keeps the slope per day
    table = fleet_table({"r": [1.0, 1.1, 1.2]})
    table["day"] = table["day"].map({"2026-01-01": "2026-01-01", "2026-01-02": "2026-01-03", "2026-01-03": "2026-01-05"})
    assert fleet.drift(table)["slope_per_day"].iloc[0] == pytest.approx(0.05)


def test_too_few_robots_give_no_outlier_score_and_empty_tables_keep_their_columns() -> None:
    table = fleet_table({"r1": [1.0, 1.0], "r2": [1.0, 2.0]})
    dr, ol = fleet.drift(table), fleet.outliers(table)
    assert ol.empty and list(ol.columns)[:2] == ["day", "robot"] and not dr["drifting"].any()
    flags = fleet.flagged_robots(dr, ol)
    assert flags.empty and list(flags.columns) == fleet.FLAG_COLUMNS


def test_a_finding_its_own_reports_explain_otherwise_carries_the_alternatives() -> None:
    nan = math.nan
    values = {f"r{i}": [nan, nan, nan] for i in range(5)}
    values["loaded"] = [nan, 1.5, 1.5]
    table = fleet_table(values, 0.01, "payload", "", "mass", "kg")
    alt = {"alternatives": [{"effects": ["inertial_error"], "why": "a payload and an inertial error of the last link are the same dynamics"}, {"effects": ["payload", "armature"], "why": "richer"}]}
    reports = {("loaded", "2026-01-02"): alt, ("loaded", "2026-01-03"): {"alternatives": []}}
    (flag,) = fleet.find(table, reports).flags.itertuples()
    assert flag.finding == "effect" and flag.alternatives == "inertial_error (1 of 2 days: a payload and an inertial error of the last link are the same dynamics)"
    assert fleet.find(table).flags["alternatives"].iloc[0] == ""
    with pytest.raises(TypeError, match="unknown threshold"):
        fleet.find(table, z_drfit=3)


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
        {"robot": "r2", "day": "d1", "status": "ok", "error": "", "report": report, "seconds": 1.5, "cpu_seconds": 0.7, "rss_start_mb": 180.0, "peak_rss_mb": 190.0, "worker": "h:1", "joint_types": {"shoulder": "revolute", "elbow": "revolute"}},
        {"robot": "r1", "day": "d1", "status": "error", "error": "LogError: bad", "report": None, "seconds": 0.1, "worker": "h:2"},
    ]
    result = fleet.FleetResult.from_results(results)
    assert list(result.tasks["robot"]) == ["r1", "r2"] and list(result.failed["error"]) == ["LogError: bad"]
    ok = result.tasks.iloc[1]
    assert ok["headline"] == "k_step" and ok["kstep_after"] == 0.004 and ok["effects"] == "coulomb_friction, payload, inertial_error"
    assert len(result.table) == 1 + 10 and list(result.reports) == [("r2", "d1")]
    assert "identifiable_directions" not in set(result.table["parameter"].dropna())
    assert "1/2 robot-days diagnosed" in repr(result)


def test_an_output_that_cannot_be_written_loses_none_of_the_others(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    from simgap.fleet.__main__ import _parser, _write

    results = [{"robot": "r1", "day": "d1", "status": "ok", "error": "", "report": REPORT, "seconds": 1.0, "worker": "h:1"}]
    result = fleet.FleetResult.from_results(results)
    args = _parser().parse_args([str(tmp_path), "--urdf", "arm.urdf"])
    found = fleet.find(result.table, result.reports)
    monkeypatch.setitem(__import__("sys").modules, "matplotlib", None)  # as if not installed
    out = tmp_path / "out"
    out.mkdir()
    failed = _write(result, found, out, args)
    assert failed == ["fleet.html"] and "could not write fleet.html: matplotlib is not installed" in capsys.readouterr().err
    assert {p.name for p in out.iterdir()} == {"fleet.parquet", "tasks.csv", "drift.csv", "outliers.csv", "flagged.csv", "reports"}
    assert len(pd.read_parquet(out / "fleet.parquet")) == len(result.table) and (out / "reports" / "r1" / "d1.json").is_file()
    back = fleet.FleetResult.read(out)
    assert list(back.table.columns) == fleet.TABLE_COLUMNS and back.table["identified"].sum() == result.table["identified"].sum()


def test_a_single_odd_robot_day_is_not_reported_until_it_recurs() -> None:
    values = {f"r{i}": [1.7 + 0.01 * i] * 4 for i in range(5)}
    values["odd"] = [1.7, 2.6, 1.7, 1.7]
    table = fleet_table(values)
    assert fleet.find(table).outliers["outlier"].sum() == 1 and fleet.find(table).flags.empty
    (flag,) = fleet.find(table, min_flagged_days=1).flags.itertuples()
    assert (flag.robot, flag.finding, flag.since, flag.test) == ("odd", "outlier", "2026-01-02", "fleet")
    values["odd"] = [1.7, 2.6, 2.6, 1.7]
    assert list(fleet.find(fleet_table(values)).flags["robot"]) == ["odd"]


def test_the_change_fleet_rejects_change_days_outside_its_days(tmp_path: Path) -> None:
    from simgap.fleet.synthetic import make_change_fleet

    with pytest.raises(ValueError, match="step_day = 4: expected 1 to 2 for 3 days"):
        make_change_fleet(tmp_path, days=3)
    with pytest.raises(ValueError, match="clean"):
        make_change_fleet(tmp_path, clean=-1)
    assert not any(tmp_path.iterdir()), "nothing written"
