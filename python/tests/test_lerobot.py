"""LeRobot datasets through the bindings: datasets of both layouts (v2.1, one Parquet file per
episode; v3.0, episodes packed in one file) written here with pyarrow as LeRobot lays them out,
read by ``simgap.read_logs`` / ``read_log`` through the Rust reader; the calibration file; the
model joint a dataset leaves out locked by ``simgap.diagnose``; every kind of bad input a
LogError naming the folder, the file and the episode; and the SAGE SO-101 dataset in
``../shared/data/sage-so101`` against SAGE's own CSVs (skipped with a message without the data,
failed when ``CI`` is set).
"""

from __future__ import annotations

import gzip
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

import simgap

pa = pytest.importorskip("pyarrow")
# every dataset here has a gripper without calibration: its warning is checked once, below
pytestmark = pytest.mark.filterwarnings("ignore:.*range-normalised:UserWarning")
pq = pytest.importorskip("pyarrow.parquet")

REPO = Path(__file__).resolve().parents[2]
SAGE = REPO.parent / "shared" / "data" / "sage-so101"

ARM = ["shoulder_pan", "shoulder_lift", "elbow_flex"]
NAMES = [f"{j}.pos" for j in ARM] + ["gripper.pos"]
FPS = 30


def motion(episode: int, frames: int) -> tuple[np.ndarray, np.ndarray]:
    """(state, action) in LeRobot's units: arm degrees, gripper 0–100; float32 like LeRobot."""
    f = np.arange(frames)[:, None]
    arm = 20.0 * np.sin(0.05 * f * (1 + np.arange(len(ARM))) + episode)
    gripper = 50.0 + 40.0 * np.sin(0.03 * f)
    state = np.hstack([arm, gripper]).astype(np.float32)
    action = np.hstack([arm + 1.5, gripper]).astype(np.float32)
    return state, action


def feature(n: int, names: list[str], dtype: str = "float32") -> dict:
    return {"dtype": dtype, "shape": [n], "names": names}


def info_json(version: str, episodes: dict[int, int], names: list[str] = NAMES, **extra: object) -> dict:
    info = {
        "codebase_version": version,
        "robot_type": "so101_follower",
        "total_episodes": len(episodes),
        "total_frames": sum(episodes.values()),
        "chunks_size": 1000,
        "fps": FPS,
        "data_path": (
            "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet" if version == "v3.0" else "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet"
        ),
        "video_path": None,
        "features": {
            "action": feature(len(names), names),
            "observation.state": feature(len(names), names),
            "timestamp": {"dtype": "float32", "shape": [1], "names": None},
            "frame_index": {"dtype": "int64", "shape": [1], "names": None},
            "episode_index": {"dtype": "int64", "shape": [1], "names": None},
            "index": {"dtype": "int64", "shape": [1], "names": None},
            "task_index": {"dtype": "int64", "shape": [1], "names": None},
        },
    }
    info.update(extra)
    return info


def episode_table(episode: int, frames: int, start: int, fixed: bool, state: np.ndarray | None = None) -> pa.Table:
    st, ac = motion(episode, frames)
    st = st if state is None else state
    width = st.shape[1]
    vec = (lambda a: pa.FixedSizeListArray.from_arrays(pa.array(a.ravel()), width)) if fixed else (lambda a: pa.array(list(a)))
    return pa.table(
        {
            "observation.state": vec(st),
            "action": vec(ac),
            "timestamp": pa.array(np.arange(frames, dtype=np.float32) / FPS),
            "frame_index": pa.array(np.arange(frames, dtype=np.int64)),
            "episode_index": pa.array(np.full(frames, episode, dtype=np.int64)),
            "index": pa.array(np.arange(start, start + frames, dtype=np.int64)),
            "task_index": pa.array(np.zeros(frames, dtype=np.int64)),
        }
    )


def write_v30(root: Path, episodes: dict[int, int]) -> Path:
    """A v3.0 dataset: every episode in data/chunk-000/file-000.parquet, one row group each, and
    the episode index in meta/episodes/chunk-000/file-000.parquet."""
    (root / "meta" / "episodes" / "chunk-000").mkdir(parents=True)
    (root / "data" / "chunk-000").mkdir(parents=True)
    (root / "meta" / "info.json").write_text(json.dumps(info_json("v3.0", episodes), indent=4))
    tables, rows, start = [], [], 0
    for e, n in episodes.items():
        tables.append(episode_table(e, n, start, fixed=True))
        rows.append({"episode_index": e, "tasks": ["wave"], "length": n, "data/chunk_index": 0, "data/file_index": 0, "dataset_from_index": start, "dataset_to_index": start + n})
        start += n
    with pq.ParquetWriter(root / "data" / "chunk-000" / "file-000.parquet", tables[0].schema) as w:
        for t in tables:
            w.write_table(t)
    pq.write_table(pa.Table.from_pylist(rows), root / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
    return root


def write_v21(root: Path, episodes: dict[int, int]) -> Path:
    """A v2.1 dataset: one file per episode (HF datasets' variable lists), meta/episodes.jsonl."""
    (root / "meta").mkdir(parents=True)
    (root / "data" / "chunk-000").mkdir(parents=True)
    (root / "meta" / "info.json").write_text(json.dumps(info_json("v2.1", episodes), indent=4))
    lines, start = [], 0
    for e, n in episodes.items():
        pq.write_table(episode_table(e, n, start, fixed=False), root / "data" / "chunk-000" / f"episode_{e:06d}.parquet")
        lines.append(json.dumps({"episode_index": e, "tasks": ["wave"], "length": n}))
        start += n
    (root / "meta" / "episodes.jsonl").write_text("\n".join(lines) + "\n")
    return root


EPISODES = {0: 90, 1: 60, 2: 75}


@pytest.fixture(params=["v2.1", "v3.0"])
def dataset(request: pytest.FixtureRequest, tmp_path: Path) -> Path:
    write = write_v21 if request.param == "v2.1" else write_v30
    return write(tmp_path / f"ds-{request.param}", EPISODES)


def test_each_episode_is_a_run_in_radians_with_nominal_time(dataset: Path) -> None:
    with pytest.warns(UserWarning, match="gripper"):
        runs = simgap.read_logs(dataset)
    assert [r.source for r in runs] == [f"{dataset}#{e}" for e in EPISODES]
    for (e, n), run in zip(EPISODES.items(), runs):
        state, action = motion(e, n)
        assert run.joints == ARM and run.left_out == ["gripper"]
        np.testing.assert_allclose(run.t, np.arange(n) / FPS, rtol=0, atol=1e-12)
        np.testing.assert_allclose(run.q, np.radians(state[:, :3].astype(np.float64)), rtol=0, atol=1e-12)
        np.testing.assert_allclose(run.q_ref, np.radians(action[:, :3].astype(np.float64)), rtol=0, atol=1e-12)
        assert any("nominal" in note for note in run.notes)
    one = simgap.read_log(f"{dataset}#1")
    assert one.source == f"{dataset}#1" and len(one) == EPISODES[1]


def test_both_layouts_give_the_same_runs(tmp_path: Path) -> None:
    a = simgap.read_logs(write_v21(tmp_path / "a", EPISODES))
    b = simgap.read_logs(write_v30(tmp_path / "b", EPISODES))
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x.q, y.q)
        np.testing.assert_array_equal(x.q_ref, y.q_ref)


def test_a_selection_picks_episodes_in_its_order(dataset: Path) -> None:
    runs = simgap.read_logs(f"{dataset}#2,0-1")
    assert [r.source.rsplit("#", 1)[1] for r in runs] == ["2", "0", "1"]
    assert simgap.lerobot_episodes(dataset) == [0, 1, 2]
    with pytest.raises(simgap.LogError, match="read_logs"):
        simgap.read_log(dataset)


def test_a_calibration_file_makes_the_gripper_an_angle(dataset: Path, tmp_path: Path) -> None:
    cal = tmp_path / "so101.json"
    for drive_mode in (0, 1):
        cal.write_text(json.dumps({"gripper": {"id": 6, "drive_mode": drive_mode, "homing_offset": 12, "range_min": 1800, "range_max": 3100}}))
        run = simgap.read_log(f"{dataset}#0", calibration=cal)
        assert run.joints == ARM + ["gripper"] and run.left_out == []
        # LeRobot: v = 100 (raw − min)/(max − min) (100 − that when mirrored); degrees (raw − mid)·360/4095
        v = motion(0, EPISODES[0])[0][:, 3].astype(np.float64)
        v = 100 - v if drive_mode else v
        raw = 1800 + v / 100 * 1300
        np.testing.assert_allclose(run.q[:, 3], np.radians((raw - 2450) * 360 / 4095), rtol=0, atol=1e-12)


def test_the_sidecar_experiment_loses_the_joint_left_out(dataset: Path) -> None:
    exp = {"controller": "servo", "joints": ARM + ["gripper"], "duty_gain": [2.6, 2.6, 2.6, 1.0], "max_duty": 0.97, "supply_voltage": 12}
    (dataset / "meta" / "simgap.experiment.json").write_text(json.dumps(exp))
    run = simgap.read_log(f"{dataset}#0")
    assert run.experiment is not None
    assert run.experiment["joints"] == ",".join(ARM)
    assert run.experiment["duty_gain"] == "2.6,2.6,2.6"
    assert math.isclose(float(run.experiment["sample_period"]), 1 / FPS)
    # joints= puts the columns in a model's order; the joint left out is skipped
    reordered = simgap.read_log(f"{dataset}#0", joints=["elbow_flex", "shoulder_pan", "shoulder_lift", "gripper"])
    assert reordered.joints == ["elbow_flex", "shoulder_pan", "shoulder_lift"]


GRIPPER_ARM_URDF = """<robot name="arm_with_jaw">
  <link name="base"/>
  {links}
</robot>"""


def arm_urdf() -> str:
    """Three revolute joints and a gripper joint at the end, named as the dataset's."""
    parts, parent = [], "base"
    for i, j in enumerate(ARM + ["gripper"]):
        child = f"link{i}"
        mass = 0.02 if j == "gripper" else 0.5
        parts.append(
            f'<link name="{child}"><inertial><origin xyz="0.1 0 0"/><mass value="{mass}"/>'
            f'<inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial></link>'
            f'<joint name="{j}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="0.2 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="5" velocity="5"/></joint>'
        )
        parent = child
    return GRIPPER_ARM_URDF.format(links="\n  ".join(parts))


def test_the_diagnosis_locks_the_joint_a_dataset_leaves_out(dataset: Path, tmp_path: Path) -> None:
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(arm_urdf())
    model = simgap.Model.from_urdf(urdf)
    assert model.joint_names == ARM + ["gripper"]
    # no experiment: the diagnosis gets past the joints (the gripper locked, not refused) and
    # stops at what a run without an experiment lacks
    with pytest.raises(simgap.LogError) as err:
        simgap.diagnose(model, f"{dataset}#0", f"{dataset}#1")
    assert "gripper" not in str(err.value) and "not in the log" not in str(err.value), err.value


# --- bad input ------------------------------------------------------------------------------


def error_of(path: object, **kw: object) -> str:
    with pytest.raises(simgap.LogError) as err:
        simgap.read_logs(path, **kw)  # type: ignore[arg-type]
    return str(err.value)


def test_a_folder_without_info_json_is_named(dataset: Path) -> None:
    (dataset / "meta" / "info.json").unlink()
    m = error_of(dataset)
    assert str(dataset) in m and "meta/info.json" in m


def test_an_episode_the_dataset_lacks_is_named(dataset: Path) -> None:
    m = error_of(f"{dataset}#1,7")
    assert str(dataset) in m and "no episode 7" in m and "0 to 2" in m


@pytest.mark.parametrize(
    "key, value, needle",
    [
        ("fps", 0, "fps"),
        ("fps", -30, "fps"),
        ("fps", "thirty", "fps"),
        ("total_episodes", -3, "total_episodes"),
        ("chunks_size", 0, "chunks_size"),
        ("codebase_version", "v1.6", "codebase_version"),
        ("data_path", "../../elsewhere/{episode_index}.parquet", "data_path"),
    ],
)
def test_hostile_info_json_values_are_refused(dataset: Path, key: str, value: object, needle: str) -> None:
    info = json.loads((dataset / "meta" / "info.json").read_text())
    info[key] = value
    (dataset / "meta" / "info.json").write_text(json.dumps(info))
    m = error_of(f"{dataset}#0")
    assert str(dataset) in m and "meta/info.json" in m and needle in m


@pytest.mark.parametrize("shape", [[10**12], [4, 4], [0], [-1]])
def test_a_huge_or_odd_shape_is_refused_before_anything_is_read(dataset: Path, shape: list[int]) -> None:
    info = json.loads((dataset / "meta" / "info.json").read_text())
    info["features"]["observation.state"]["shape"] = shape
    (dataset / "meta" / "info.json").write_text(json.dumps(info))
    m = error_of(dataset)
    assert "observation.state" in m and "shape" in m


def data_file(dataset: Path, episode: int) -> Path:
    v3 = dataset / "data" / "chunk-000" / "file-000.parquet"
    return v3 if v3.exists() else dataset / "data" / "chunk-000" / f"episode_{episode:06d}.parquet"


@pytest.mark.parametrize("keep", [0.0, 0.3, 0.9, 0.999])
def test_a_truncated_parquet_file_is_named_with_its_episode(dataset: Path, keep: float) -> None:
    f = data_file(dataset, 1)
    data = f.read_bytes()
    f.write_bytes(data[: int(len(data) * keep)])
    m = error_of(f"{dataset}#1")
    assert str(dataset) in m and f.name in m and "episode 1" in m


def test_mutated_parquet_files_give_runs_or_clean_errors(dataset: Path) -> None:
    f = data_file(dataset, 0)
    clean = f.read_bytes()
    rng = np.random.default_rng(54)
    refused = 0
    for _ in range(60):
        data = bytearray(clean)
        for at in rng.integers(0, len(data), size=int(rng.integers(1, 6))):
            data[at] = int(rng.integers(0, 256))
        f.write_bytes(bytes(data))
        try:
            simgap.read_logs(f"{dataset}#0")
        except simgap.LogError as err:
            refused += 1
            assert str(dataset) in str(err) and "internal error" not in str(err)
    f.write_bytes(clean)
    assert refused > 0


def rewrite_episode(dataset: Path, episode: int, state: pa.Array) -> None:
    """Replaces the observation.state column of an episode's file."""
    f = data_file(dataset, episode)
    t = pq.read_table(f)
    t = t.set_column(t.schema.get_field_index("observation.state"), "observation.state", state)
    pq.write_table(t, f)


def test_a_non_float_state_column_is_refused(dataset: Path) -> None:
    f = data_file(dataset, 0)
    rows = pq.read_metadata(f).num_rows
    rewrite_episode(dataset, 0, pa.array([[1, 2, 3, 4]] * rows, type=pa.list_(pa.int64())))
    m = error_of(f"{dataset}#0")
    assert str(dataset) in m and f.name in m and "observation.state" in m and "integers" in m
    rewrite_episode(dataset, 0, pa.array([["a", "b", "c", "d"]] * rows))
    m = error_of(f"{dataset}#0")
    assert "observation.state" in m and "numbers" in m


def test_nulls_and_ragged_rows_are_refused(dataset: Path) -> None:
    f = data_file(dataset, 0)
    rows = pq.read_metadata(f).num_rows
    ragged = [[1.0, 2.0, 3.0, 4.0]] * (rows - 1) + [[1.0, 2.0]]
    rewrite_episode(dataset, 0, pa.array(ragged, type=pa.list_(pa.float32())))
    assert "observation.state" in error_of(f"{dataset}#0")
    nulls = [[1.0, 2.0, 3.0, 4.0]] * (rows - 1) + [[1.0, None, 3.0, 4.0]]
    rewrite_episode(dataset, 0, pa.array(nulls, type=pa.list_(pa.float32())))
    assert "null" in error_of(f"{dataset}#0")


def test_a_gripper_outside_0_to_100_is_no_range_normalised_joint(dataset: Path, tmp_path: Path) -> None:
    f = data_file(dataset, 0)
    rows = pq.read_metadata(f).num_rows
    rewrite_episode(dataset, 0, pa.array([[1.0, 2.0, 3.0, 150.0]] * rows, type=pa.list_(pa.float32())))
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps({"gripper": {"id": 6, "drive_mode": 0, "homing_offset": 0, "range_min": 1000, "range_max": 2000}}))
    m = error_of(f"{dataset}#0", calibration=cal)
    assert "gripper.pos" in m and "0–100" in m and "episode 0" in m


def test_frames_missing_against_the_episode_metadata_are_refused(dataset: Path) -> None:
    if (dataset / "meta" / "episodes.jsonl").exists():
        lines = (dataset / "meta" / "episodes.jsonl").read_text().splitlines()
        lines[1] = json.dumps({"episode_index": 1, "tasks": ["wave"], "length": 61})
        (dataset / "meta" / "episodes.jsonl").write_text("\n".join(lines) + "\n")
    else:
        p = dataset / "meta" / "episodes" / "chunk-000" / "file-000.parquet"
        t = pq.read_table(p).to_pylist()
        t[1]["dataset_to_index"] += 1
        pq.write_table(pa.Table.from_pylist(t), p)
    m = error_of(f"{dataset}#1")
    assert "episode 1" in m and "61" in m


def test_a_bad_calibration_file_is_named(dataset: Path, tmp_path: Path) -> None:
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps({"gripper": {"id": 6, "drive_mode": 0, "homing_offset": 0, "range_min": 2000, "range_max": 1000}}))
    m = error_of(dataset, calibration=cal)
    assert "cal.json" in m and "gripper" in m and "range_min" in m


# --- the fleet ------------------------------------------------------------------------------


def test_the_fleet_index_lists_a_datasets_episodes(tmp_path: Path) -> None:
    pytest.importorskip("pandas")
    from simgap.fleet import index_from_folder

    write_v30(tmp_path / "fleet" / "so101-a" / "2026-01-05" / "session", EPISODES)
    index = index_from_folder(tmp_path / "fleet")
    assert list(index["path"]) == [f"{tmp_path}/fleet/so101-a/2026-01-05/session#{e}" for e in EPISODES]
    assert list(index["role"]) == ["fit", "fit", "holdout"]


# --- the SAGE SO-101 dataset ----------------------------------------------------------------


@pytest.fixture(scope="module")
def sage() -> Path:
    if not (SAGE / "lerobot" / "meta" / "info.json").is_file():
        msg = f"the SAGE SO-101 data is not at {SAGE}"
        if os.environ.get("CI"):
            pytest.fail(f"{msg} (CI is set: a test without its data fails)")
        pytest.skip(msg)
    return SAGE


def sage_positions(path: Path) -> tuple[np.ndarray, np.ndarray]:
    with gzip.open(path, "rt") as f:
        lines = f.read().splitlines()[1:]
    t, q = [], []
    for line in lines:
        _kind, stamp, rest = line.split(",", 2)
        t.append(float(stamp) * 1e-6)
        q.append(json.loads(rest.split('"')[1]))
    return np.array(t), np.array(q)


def test_sage_so101_degrees_are_sages_radians(sage: Path) -> None:
    run = simgap.read_log(f"{sage / 'lerobot'}#4")
    assert run.source.endswith("lerobot#4") and run.joints == ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"]
    # chirp_sweep: states linearly interpolated onto t0 + f/50 s, degrees as LeRobot writes them
    # ((raw − mid)·360/4095): radians(state) = SAGE's radians × 4096/4095
    ts, qs = sage_positions(sage / "sage" / "chirp_sweep" / "state_motor.csv.gz")
    expected = np.column_stack([np.interp(ts[0] + run.t, ts, qs[:, j]) for j in range(5)]) * 4096 / 4095
    assert np.abs(run.q - expected).max() < 5e-6


def test_sage_so101_with_the_published_urdf_gets_past_its_gripper(sage: Path) -> None:
    model = simgap.Model.from_urdf(sage / "so101_new_calib.urdf")
    assert "gripper" in model.joint_names
    with pytest.raises(simgap.LogError) as err:
        simgap.diagnose(model, f"{sage / 'lerobot'}#36", f"{sage / 'lerobot'}#29")
    assert "gripper" not in str(err.value) and "not in the log" not in str(err.value), err.value


@pytest.mark.slow
def test_a_simulated_servo_dataset_is_diagnosed_with_its_gripper_locked_and_its_timing_noted(tmp_path: Path) -> None:
    # three servo runs of the arm, its gripper held: written as a v3.0 dataset in LeRobot's
    # units (degrees, the gripper 0–100) with the experiment as its sidecar
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(arm_urdf())
    model = simgap.Model.from_urdf(urdf)
    exp = {"controller": "servo", "joints": ",".join(ARM + ["gripper"]), "duty_gain": 2, "supply_voltage": 12, "kt": 0.3, "R": 3.0, "sample_period": 0.005}
    runs = [simgap.simulate(model, target, experiment=exp, duration=5.0, counts_per_rev=None) for target in ([0.4, -0.3, 0.5, 0.0], [-0.2, 0.5, -0.4, 0.0], [0.3, 0.2, -0.2, 0.0])]
    ds = tmp_path / "ds"
    (ds / "meta" / "episodes" / "chunk-000").mkdir(parents=True)
    (ds / "data" / "chunk-000").mkdir(parents=True)
    info = info_json("v3.0", {e: len(r) for e, r in enumerate(runs)})
    info["fps"] = 200
    (ds / "meta" / "info.json").write_text(json.dumps(info))
    (ds / "meta" / "simgap.experiment.json").write_text(json.dumps({k: v for k, v in exp.items() if k != "sample_period"}))
    vec = lambda a: pa.FixedSizeListArray.from_arrays(pa.array(a.astype(np.float32).ravel()), 4)  # noqa: E731
    tables, rows, start = [], [], 0
    for e, r in enumerate(runs):
        n = len(r)
        state, goal = np.degrees(r.q), np.degrees(r.q_ref)
        state[:, 3] = goal[:, 3] = 50.0
        tables.append(pa.table({"observation.state": vec(state), "action": vec(goal), "frame_index": pa.array(np.arange(n)), "episode_index": pa.array(np.full(n, e))}))
        rows.append({"episode_index": e, "length": n, "data/chunk_index": 0, "data/file_index": 0, "dataset_from_index": start, "dataset_to_index": start + n})
        start += n
    with pq.ParquetWriter(ds / "data" / "chunk-000" / "file-000.parquet", tables[0].schema) as w:
        for t in tables:
            w.write_table(t)
    pq.write_table(pa.Table.from_pylist(rows), ds / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
    report = simgap.diagnose(model, f"{ds}#0-1", f"{ds}#2")
    assert report["joints"] == ARM
    assert report["holdout_logs"] == [f"{ds}#2"]
    notes = "\n".join(report.notes)
    assert f"{ds}#0, {ds}#1, {ds}#2: LeRobot timestamps are nominal" in notes
    assert "'gripper'" in notes and "locked" in notes
