"""MCAP interoperability with the ROS 2 Python tooling.

- a JointState bag written by ``mcap_ros2.writer.Writer`` (joints shuffled per message, absolute
  stamps, zstd or lz4 chunks, ``simgap.experiment`` metadata) reads in simgap;
- an MCAP written by simgap decodes with ``mcap_ros2`` (schema, channels, QoS metadata,
  stamps to the nanosecond, values by joint name, metadata);
- a file cut short (its writer killed) is recovered up to its last complete chunk, with a
  warning.

simgap is driven through the example ``log_roundtrip`` (read a log, print a JSON summary,
optionally write it again), built here with cargo; ``simgap simulate --out`` is checked too
once it exists.
"""

from __future__ import annotations

import json
import os
import random
import shlex
import subprocess
from pathlib import Path

import pytest

mcap_reader = pytest.importorskip("mcap.reader")
mcap_ros2_writer = pytest.importorskip("mcap_ros2.writer")
mcap_ros2_decoder = pytest.importorskip("mcap_ros2.decoder")
from mcap.writer import CompressionType  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]

JOINT_STATE_MSGDEF = """\
std_msgs/Header header

string[] name
float64[] position
float64[] velocity
float64[] effort

================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id

================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""

JOINTS = ["shoulder", "elbow", "wrist"]
T0_SEC = 1_712_345_678
DT_NS = 2_500_000
N = 200


@pytest.fixture(scope="session")
def roundtrip_bin() -> Path:
    """The `log_roundtrip` example, built in release mode (its path from cargo's own output)."""
    try:
        out = subprocess.run(
            ["cargo", "build", "--release", "--example", "log_roundtrip", "--message-format=json"],
            cwd=ROOT,
            check=True,
            capture_output=True,
            text=True,
            timeout=1800,
        ).stdout
    except FileNotFoundError:
        pytest.skip("cargo is not installed: cannot build the log_roundtrip example")
    for line in out.splitlines():
        try:
            msg = json.loads(line)
        except json.JSONDecodeError:
            continue
        if msg.get("reason") == "compiler-artifact" and msg.get("target", {}).get("name") == "log_roundtrip" and msg.get("executable"):
            return Path(msg["executable"])
    raise AssertionError("cargo built log_roundtrip but did not report its executable")


def simgap_summary(binary: Path, log: Path, out: Path | None = None) -> dict:
    args = [str(binary), str(log)] + ([str(out)] if out else [])
    done = subprocess.run(args, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def value(joint: str, k: int) -> float:
    """Position of `joint` at sample `k`: tells joints apart whatever their order."""
    return JOINTS.index(joint) * 10.0 + k * 0.001


def write_ros2_bag(path: Path, compression: CompressionType) -> None:
    rng = random.Random(7)
    with open(path, "wb") as f:
        writer = mcap_ros2_writer.Writer(f, compression=compression, chunk_size=4096)
        schema = writer.register_msgdef("sensor_msgs/msg/JointState", JOINT_STATE_MSGDEF)
        writer._writer.add_metadata(  # the mcap writer underneath: metadata records
            "simgap.experiment",
            {"controller": "pd", "joints": "elbow,shoulder,wrist", "kp": "32.36,64.72,5", "kv": "6.472,48.54,0.5", "sample_period": "0.0025", "robot": "test arm"},
        )
        for k in range(N):
            ns = k * DT_NS
            names = JOINTS[:] if k == 0 else rng.sample(JOINTS, len(JOINTS))
            stamp = {"sec": T0_SEC + ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}
            log_time = T0_SEC * 1_000_000_000 + ns
            writer.write_message(
                "/joint_states",
                schema,
                {
                    "header": {"stamp": stamp, "frame_id": ""},
                    "name": names,
                    "position": [value(j, k) for j in names],
                    "velocity": [JOINTS.index(j) + 0.5 for j in names],
                    "effort": [-value(j, k) for j in names],
                },
                log_time=log_time,
                publish_time=log_time,
            )
            ref_names = rng.sample(JOINTS, len(JOINTS))
            writer.write_message(
                "/joint_reference",
                schema,
                {"header": {"stamp": stamp, "frame_id": ""}, "name": ref_names, "position": [100.0 + JOINTS.index(j) for j in ref_names], "velocity": [], "effort": []},
                log_time=log_time,
                publish_time=log_time,
            )
        writer.finish()


@pytest.mark.parametrize("compression", [CompressionType.ZSTD, CompressionType.LZ4], ids=["zstd", "lz4"])
def test_simgap_reads_a_bag_written_by_mcap_ros2(tmp_path: Path, roundtrip_bin: Path, compression: CompressionType) -> None:
    bag = tmp_path / "ros2.mcap"
    write_ros2_bag(bag, compression)
    s = simgap_summary(roundtrip_bin, bag)
    assert s["joints"] == JOINTS  # the first message's order
    assert s["samples"] == N
    assert s["start_ns"] == T0_SEC * 1_000_000_000  # the absolute start, to the nanosecond
    assert s["t_first"] == 0.0  # time since the start
    assert s["duration"] == pytest.approx((N - 1) * DT_NS * 1e-9, abs=1e-6)
    for j in JOINTS:  # mapped by name although every message shuffles them
        assert s["q_first"][j] == pytest.approx(value(j, 0))
        assert s["q_last"][j] == pytest.approx(value(j, N - 1))
        assert s["qd_last"][j] == pytest.approx(JOINTS.index(j) + 0.5)
        assert s["tau_last"][j] == pytest.approx(-value(j, N - 1))
        assert s["q_ref_last"][j] == pytest.approx(100.0 + JOINTS.index(j))
    assert s["experiment"]["controller"] == "pd"
    assert s["experiment"]["joints"] == "elbow,shoulder,wrist"
    assert s["experiment"]["robot"] == "test arm"


def check_simgap_mcap(path: Path, expect_reference: bool = True) -> dict[str, list]:
    """Decodes an MCAP written by simgap with mcap_ros2; returns decoded messages per topic."""
    topics: dict[str, list] = {}
    with open(path, "rb") as f:
        reader = mcap_reader.make_reader(f, decoder_factories=[mcap_ros2_decoder.DecoderFactory()])
        header = reader.get_header()
        assert header.profile == "ros2"
        summary = reader.get_summary()
        assert summary is not None, "simgap always writes the summary"
        by_topic = {c.topic: c for c in summary.channels.values()}
        for topic in ["/joint_states"] + (["/joint_reference"] if expect_reference else []):
            channel = by_topic[topic]
            assert channel.message_encoding == "cdr"
            assert "offered_qos_profiles" in channel.metadata
            schema = summary.schemas[channel.schema_id]
            assert (schema.name, schema.encoding) == ("sensor_msgs/msg/JointState", "ros2msg")
            assert "MSG: std_msgs/Header" in schema.data.decode() and "MSG: builtin_interfaces/Time" in schema.data.decode()
        for _schema, channel, message, decoded in reader.iter_decoded_messages(topics=["/joint_states", "/joint_reference"]):
            topics.setdefault(channel.topic, []).append((message, decoded))
    return topics


def read_metadata(path: Path) -> dict[str, dict[str, str]]:
    with open(path, "rb") as f:
        return {m.name: dict(m.metadata) for m in mcap_reader.make_reader(f).iter_metadata()}


def test_mcap_ros2_reads_an_mcap_written_by_simgap(tmp_path: Path, roundtrip_bin: Path) -> None:
    bag = tmp_path / "ros2.mcap"
    write_ros2_bag(bag, CompressionType.ZSTD)
    out = tmp_path / "simgap.mcap"
    simgap_summary(roundtrip_bin, bag, out)
    topics = check_simgap_mcap(out)
    states = topics["/joint_states"]
    assert len(states) == N and len(topics["/joint_reference"]) == N
    for k, (message, m) in enumerate(states):
        ns = k * DT_NS
        # simgap keeps stamps as integer nanoseconds: the originals, exactly
        stamp_ns = m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
        assert stamp_ns == T0_SEC * 1_000_000_000 + ns
        assert message.log_time == stamp_ns
        assert list(m.name) == JOINTS
        assert list(m.position) == pytest.approx([value(j, k) for j in JOINTS])
        assert list(m.effort) == pytest.approx([-value(j, k) for j in JOINTS])
    _, ref = topics["/joint_reference"][-1]
    assert list(ref.position) == [100.0, 101.0, 102.0]
    assert list(ref.effort) == []
    meta = read_metadata(out)["simgap.experiment"]
    assert meta["controller"] == "pd" and meta["kp"] == "32.36,64.72,5" and meta["sample_period"] == "0.0025"
    assert meta["robot"] == "test arm"
    # and simgap reads its own file back to the same summary
    assert simgap_summary(roundtrip_bin, out)["q_last"] == simgap_summary(roundtrip_bin, bag)["q_last"]


def test_truncated_bag_is_recovered_with_a_warning(tmp_path: Path, roundtrip_bin: Path) -> None:
    bag = tmp_path / "whole.mcap"
    write_ros2_bag(bag, CompressionType.ZSTD)
    cut = tmp_path / "half.mcap"
    data = bag.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    s = simgap_summary(roundtrip_bin, cut)
    assert 0 < s["samples"] < N
    assert any("no summary" in w and f"of {len(data) // 2}" in w for w in s["warnings"]), s["warnings"]
    # cut before any message: an error naming the file
    head = tmp_path / "head.mcap"
    head.write_bytes(data[:64])
    done = subprocess.run([str(roundtrip_bin), str(head)], capture_output=True, text=True, timeout=300)
    assert done.returncode != 0
    assert str(head) in done.stderr and "truncated" in done.stderr


def test_simgap_simulate_out_decodes_with_mcap_ros2(tmp_path: Path) -> None:
    binary = os.environ.get("SIMGAP_BIN")
    if not binary:
        pytest.skip("SIMGAP_BIN is not set (make test sets it to the release simgap binary)")
    help_text = subprocess.run([binary, "simulate", "--help"], capture_output=True, text=True, timeout=60).stdout
    if "--out" not in help_text:
        pytest.skip("`simgap simulate --out` does not exist yet")
    out = tmp_path / "sim.mcap"
    extra = shlex.split(os.environ.get("SIMGAP_SIMULATE_ARGS", ""))
    done = subprocess.run([binary, "simulate", "--out", str(out), *extra], capture_output=True, text=True, timeout=600)
    if done.returncode != 0 and "required" in done.stderr:
        pytest.skip(f"`simgap simulate` needs more arguments (set SIMGAP_SIMULATE_ARGS): {done.stderr.strip()}")
    assert done.returncode == 0, done.stderr
    topics = check_simgap_mcap(out, expect_reference=False)
    assert len(topics["/joint_states"]) > 1
    assert "simgap.experiment" in read_metadata(out)
