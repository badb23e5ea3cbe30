"""Every file simgap writes opens in the ROS 2 Python tooling, and simgap reads what it writes.

- ``rosbags`` (``Reader`` on the file and on a bag folder holding it with ``metadata.yaml``,
  ``AnyReader`` with deserialisation of every message) and ``mcap_ros2``'s
  ``read_ros2_messages`` open the logs of ``simgap simulate``, ``simgap paper``, ``simgap demo``
  (its logs and ``corrected.mcap``) and ``simgap.write_log``: every channel is CDR with a
  ``ros2msg`` schema, run status is in metadata records only.
- A bag written by ``rosbags``' own writer (joints shuffled per message, two publishers on one
  topic, absolute stamps, a topic named after the robot) reads in simgap, mapped by name.
"""

from __future__ import annotations

import json
import os
import random
import subprocess
from pathlib import Path

import numpy as np
import pytest

rosbags_rosbag2 = pytest.importorskip("rosbags.rosbag2")
rosbags_highlevel = pytest.importorskip("rosbags.highlevel")
rosbags_typesys = pytest.importorskip("rosbags.typesys")
mcap_ros2_reader = pytest.importorskip("mcap_ros2.reader")
mcap_reader = pytest.importorskip("mcap.reader")
simgap = pytest.importorskip("simgap")

T0_NS = 1_733_000_000_123_456_789
DT_NS = 2_000_000
N = 150


def simgap_bin() -> str:
    binary = os.environ.get("SIMGAP_BIN")
    if not binary:
        pytest.skip("SIMGAP_BIN is not set (make test sets it to the release simgap binary)")
    return binary


def run_simgap(*args: str) -> None:
    done = subprocess.run([simgap_bin(), *args], capture_output=True, text=True, timeout=1200)
    assert done.returncode == 0, done.stderr


def bag_folder(mcap_file: Path, folder: Path) -> Path:
    """A rosbag2 folder holding a copy of `mcap_file` and the metadata.yaml rosbag2 would write."""
    folder.mkdir()
    target = folder / mcap_file.name
    target.write_bytes(mcap_file.read_bytes())
    with open(target, "rb") as f:
        reader = mcap_reader.make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        stats = summary.statistics
        topics = []
        for cid, channel in summary.channels.items():
            schema = summary.schemas[channel.schema_id]
            topics.append(
                "  - message_count: {n}\n    topic_metadata:\n      name: {topic}\n      offered_qos_profiles: {qos}\n"
                "      serialization_format: {fmt}\n      type: {ty}\n      type_description_hash: ''".format(
                    n=stats.channel_message_counts.get(cid, 0),
                    topic=channel.topic,
                    qos=json.dumps(channel.metadata.get("offered_qos_profiles", "")),  # the file's QoS, as rosbag2 v8 writes it
                    fmt=channel.message_encoding,
                    ty=schema.name,
                )
            )
    yaml = (
        "rosbag2_bagfile_information:\n"
        "  version: 8\n  storage_identifier: mcap\n"
        f"  duration:\n    nanoseconds: {stats.message_end_time - stats.message_start_time}\n"
        f"  starting_time:\n    nanoseconds_since_epoch: {stats.message_start_time}\n"
        f"  message_count: {stats.message_count}\n"
        "  topics_with_message_count:\n" + "\n".join(topics) + "\n"
        "  compression_format: ''\n  compression_mode: ''\n"
        f"  relative_file_paths:\n  - {mcap_file.name}\n"
        "  files:\n"
        f"  - path: {mcap_file.name}\n    starting_time:\n      nanoseconds_since_epoch: {stats.message_start_time}\n"
        f"    duration:\n      nanoseconds: {stats.message_end_time - stats.message_start_time}\n    message_count: {stats.message_count}\n"
        "  custom_data: ~\n  ros_distro: humble\n"
    )
    (folder / "metadata.yaml").write_text(yaml)
    return folder


def open_with_ros2_tools(path: Path, tmp_path: Path) -> dict[str, int]:
    """Opens an MCAP file with rosbags (file, bag folder, AnyReader) and mcap_ros2; returns the
    message count per topic, after checking that every tool decodes every message."""
    # mcap_ros2: every message of every channel decodes
    counts: dict[str, int] = {}
    for m in mcap_ros2_reader.read_ros2_messages(str(path)):
        counts[m.channel.topic] = counts.get(m.channel.topic, 0) + 1
        assert m.schema.encoding == "ros2msg" and m.channel.message_encoding == "cdr"
        if m.schema.name == "sensor_msgs/msg/JointState":
            stamp = m.ros_msg.header.stamp.sec * 1_000_000_000 + m.ros_msg.header.stamp.nanosec
            assert stamp == m.log_time_ns
    assert counts, f"{path}: no messages"
    # rosbags Reader on the file itself
    with rosbags_rosbag2.Reader(path) as reader:
        assert {c.topic: c.msgcount for c in reader.connections} == counts
        assert sum(1 for _ in reader.messages()) == sum(counts.values())
    # rosbags Reader and AnyReader on a bag folder holding it
    folder = bag_folder(path, tmp_path / f"bag_{path.stem}")
    with rosbags_rosbag2.Reader(folder) as reader:
        assert sum(1 for _ in reader.messages()) == sum(counts.values())
    with rosbags_highlevel.AnyReader([folder]) as reader:
        seen = 0
        for connection, _timestamp, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)
            if connection.msgtype == "sensor_msgs/msg/JointState":
                assert len(msg.name) > 0
            seen += 1
        assert seen == sum(counts.values())
    with rosbags_highlevel.AnyReader([path]) as reader:
        assert sum(1 for _ in reader.messages()) == sum(counts.values())
    return counts


def test_simgap_simulate_log_opens_in_rosbags_and_mcap_ros2(tmp_path: Path) -> None:
    out = tmp_path / "sim.mcap"
    run_simgap("simulate", "--duration", "0.5", "--out", str(out))
    counts = open_with_ros2_tools(out, tmp_path)
    assert counts["/joint_states"] == 201 and counts["/joint_reference"] == 201
    with open(out, "rb") as f:
        meta = {m.name: dict(m.metadata) for m in mcap_reader.make_reader(f).iter_metadata()}
    assert meta["simgap.run_end"]["status"] == "completed"
    assert "simgap.experiment" in meta


def test_a_simulated_servo_log_opens_in_rosbags_and_mcap_ros2_with_its_drive_signals(tmp_path: Path) -> None:
    out = tmp_path / "servo.mcap"
    urdf = Path(__file__).resolve().parents[2] / "crates" / "simgap-core" / "models" / "pendulum.urdf"
    servo = ["--controller", "servo", "--duty-gain", "2", "--supply-voltage", "12", "--kt", "1.5", "--resistance", "1.5"]
    run_simgap("simulate", "--urdf", str(urdf), *servo, "--target", "0.6", "--duration", "0.5", "--out", str(out))
    counts = open_with_ros2_tools(out, tmp_path)
    assert {t: counts.get(t) for t in ["/joint_states", "/servo/duty", "/servo/torque_enable", "/servo/voltage"]} == dict.fromkeys(
        ["/joint_states", "/servo/duty", "/servo/torque_enable", "/servo/voltage"], 201
    ), counts
    # decoded by rosbags: the duty is the firmware's clip(2 (goal − q), ±1), the servo logs no torque
    with rosbags_highlevel.AnyReader([out]) as reader:
        by_topic: dict[str, list] = {}
        for connection, _timestamp, raw in reader.messages():
            by_topic.setdefault(connection.topic, []).append(reader.deserialize(raw, connection.msgtype))
    states, goals, duty = by_topic["/joint_states"], by_topic["/joint_reference"], by_topic["/servo/duty"]
    for s, g, d in zip(states, goals, duty):
        assert len(s.effort) == 0 and list(d.name) == ["hinge"]
        assert d.effort[0] == pytest.approx(np.clip(2.0 * (g.position[0] - s.position[0]), -1, 1), abs=1e-12)
    assert duty[0].effort[0] == 1.0, "the first sample's duty saturates (goal 0.6 rad away)"
    assert all(list(v.name) == ["voltage"] and v.effort[0] == 12.0 for v in by_topic["/servo/voltage"])
    assert all(e.effort[0] == 1.0 for e in by_topic["/servo/torque_enable"])


def test_simgap_paper_logs_open_in_rosbags_and_mcap_ros2(tmp_path: Path) -> None:
    run_simgap("paper", "--out-dir", str(tmp_path))
    for name in ["paper_euler_lagrange.mcap", "paper_simplified.mcap"]:
        assert open_with_ros2_tools(tmp_path / name, tmp_path)["/joint_states"] == 1201


def test_simgap_demo_logs_and_corrected_mcap_open_in_rosbags_and_mcap_ros2(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    run_simgap("demo", "--out-dir", str(out))
    logs = sorted(out.glob("*.mcap"))
    assert out / "corrected.mcap" in logs and len(logs) >= 3
    for log in logs:
        counts = open_with_ros2_tools(log, tmp_path)
        if log.name == "corrected.mcap":
            assert any(t.endswith("/measured/joint_states") for t in counts), counts
            assert any(t.endswith("/nominal/joint_states") for t in counts), counts


def test_write_log_opens_in_rosbags_with_every_channel(tmp_path: Path) -> None:
    n = 40
    t = np.arange(n) * 0.002
    q = np.stack([np.sin(t), np.cos(t)], axis=1)
    run = simgap.Run(
        ["a", "b"], t, q, -q, tau=2 * q, q_ref=q + 0.1, qd_ref=-q, tau_ff=0.5 * q, tau_measured=1.9 * q, start_ns=T0_NS,
        experiment={"controller": "pd", "joints": "a,b", "kp": "1,2", "kv": "0.1,0.2", "sample_period": "0.002"},
    )
    path = tmp_path / "written.mcap"
    simgap.write_log(run, path)
    counts = open_with_ros2_tools(path, tmp_path)
    assert counts == {"/joint_states": n, "/joint_reference": n, "/joint_effort_measured": n}
    with rosbags_highlevel.AnyReader([path]) as reader:
        stamps = [ts for c, ts, _ in reader.messages() if c.topic == "/joint_states"]
    assert stamps == [T0_NS + k * DT_NS for k in range(n)]
    back = simgap.read_log(path)
    assert back.start_ns == T0_NS
    np.testing.assert_array_equal(back.tau_ff, run.tau_ff)
    np.testing.assert_array_equal(back.tau_measured, run.tau_measured)


def write_rosbags_bag(folder: Path) -> None:
    """A bag from rosbags' own writer: an arm and a gripper publishing on one topic named after
    the robot, the arm's joints shuffled in every message, absolute stamps."""
    store = rosbags_typesys.get_typestore(rosbags_typesys.Stores.ROS2_HUMBLE)
    joint_state = store.types["sensor_msgs/msg/JointState"]
    header = store.types["std_msgs/msg/Header"]
    time = store.types["builtin_interfaces/msg/Time"]
    rng = random.Random(3)
    writer = rosbags_rosbag2.Writer(folder, version=9, storage_plugin=rosbags_rosbag2.StoragePlugin.MCAP)
    with writer:
        conn = writer.add_connection("/robot/arm_left_follow/joint_states", joint_state.__msgtype__, typestore=store)
        for k in range(N):
            ns = T0_NS + k * DT_NS
            stamp = time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
            arm = rng.sample(["shoulder", "elbow"], 2)
            values = {"shoulder": k * 0.01, "elbow": 1.0 + k * 0.01, "gripper": 0.02}
            for names in (arm, ["gripper"]):
                msg = joint_state(
                    header=header(stamp=stamp, frame_id=""),
                    name=names,
                    position=np.array([values[j] for j in names]),
                    velocity=np.array([0.5 for _ in names]),
                    effort=np.array([-values[j] for j in names]),
                )
                writer.write(conn, ns, store.serialize_cdr(msg, joint_state.__msgtype__))


def test_simgap_reads_a_bag_written_by_rosbags(tmp_path: Path) -> None:
    folder = tmp_path / "teleop"
    write_rosbags_bag(folder)
    run = simgap.read_log(folder, topics={"states": "/robot/arm_left_follow/joint_states"}, experiment={
        "controller": "replay", "joints": "", "kp": "", "kv": "", "sample_period": "0.002"})
    assert len(run) == N and run.start_ns == T0_NS and run.t[0] == 0.0
    assert run.t[-1] == pytest.approx((N - 1) * DT_NS * 1e-9, abs=1e-12)
    ordered = simgap.read_log(folder, joints=["shoulder", "elbow", "gripper"], topics={"states": "/robot/arm_left_follow/joint_states"})
    k = np.arange(N)
    np.testing.assert_allclose(ordered.q[:, 0], k * 0.01)
    np.testing.assert_allclose(ordered.q[:, 1], 1.0 + k * 0.01)
    np.testing.assert_allclose(ordered.tau[:, 2], -0.02)
    assert run.experiment is not None and run.experiment["controller"] == "replay"
    # the file alone, and the topic left at its default: an error that names the topics found
    with pytest.raises(simgap.LogError, match="arm_left_follow"):
        simgap.read_log(folder)


def test_a_killed_recorder_file_reads_with_a_warning(tmp_path: Path) -> None:
    whole = tmp_path / "long.mcap"
    run_simgap("simulate", "--duration", "30", "--out", str(whole))
    data = whole.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])  # as a recorder killed mid-write leaves it
    with pytest.warns(UserWarning, match="no summary"):
        run = simgap.read_log(cut)
    assert 1000 < len(run) < 12001
    np.testing.assert_array_equal(run.q, simgap.read_log(whole).q[: len(run)])
