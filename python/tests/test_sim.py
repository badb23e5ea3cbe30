"""Simulation, logs and the L² index through the bindings (simgap-sim)."""

from __future__ import annotations

import _thread
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import simgap
from simgap import DimensionError, LogError, Run, SimulationError

# the seed paper's experiment (§5)
TARGET = [np.pi / 4, np.pi / 2]
KP = [64.72, 32.36]
KV = [48.54, 6.472]


@pytest.fixture(scope="module")
def paper_run() -> Run:
    return simgap.simulate(simgap.Model.paper_arm(), TARGET, controller="pd", kp=KP, kv=KV)


def test_paper_experiment_runs_3_s_at_2_5_ms(paper_run: Run) -> None:
    assert paper_run.joints == ["shoulder", "elbow"]
    assert len(paper_run) == 1201 and paper_run.t.shape == (1201,) and paper_run.q.shape == (1201, 2)
    np.testing.assert_allclose(paper_run.t[[0, -1]], [0.0, 3.0])
    np.testing.assert_allclose(np.diff(paper_run.t), 0.0025, atol=1e-12)
    np.testing.assert_allclose(paper_run.q_ref[-1], TARGET)
    assert paper_run.tau is not None and paper_run.tau.shape == (1201, 2)
    # tau is the PD law on what the controller saw
    k = 600
    expected = np.array(KP) * (paper_run.q_ref[k] - paper_run.q[k]) + np.array(KV) * (0 - paper_run.qd[k])
    np.testing.assert_allclose(paper_run.tau[k], expected, rtol=1e-9, atol=1e-9)
    assert paper_run.experiment is not None and paper_run.experiment["controller"] == "pd"
    assert paper_run.source == "simulation"


def test_simulation_is_deterministic(paper_run: Run) -> None:
    again = simgap.simulate(simgap.Model.paper_arm(), TARGET, controller="pd", kp=KP, kv=KV)
    np.testing.assert_array_equal(again.q, paper_run.q)


def test_resimulating_a_run_reproduces_it(paper_run: Run) -> None:
    # controller, gains, sample period, t0, duration, q0, qd0 all default to the run's
    again = simgap.simulate(simgap.Model.paper_arm(), paper_run)
    assert simgap.compare(again, paper_run).overall < 1e-9


def test_friction_widens_the_gap(paper_run: Run) -> None:
    with_friction = simgap.simulate(
        simgap.Model.paper_arm(), TARGET, controller="pd", kp=KP, kv=KV, effects=["viscous_friction:b=2.288,0.175", "coulomb_friction:fc=7.17,1.734"]
    )
    report = simgap.compare(with_friction, paper_run)
    assert report.overall > 1e-3
    assert report.joints == ["shoulder", "elbow"] and report.per_joint.shape == (2,)
    assert report.samples == 1201 and report.span == (0.0, 3.0)


def test_backlash_acts_through_the_rotor_inertia_it_carries(paper_run: Run) -> None:
    # play without a rotor inertia leaves the run as it is (the drive side crosses the gap at
    # once); with the rotor's inertia on its drive side it changes the motion
    arm = simgap.Model.paper_arm()
    massless = simgap.simulate(arm, TARGET, controller="pd", kp=KP, kv=KV, effects=["backlash:width=0.03,0.03"])
    np.testing.assert_array_equal(massless.q, paper_run.q)
    rotor = simgap.simulate(arm, TARGET, controller="pd", kp=KP, kv=KV, effects=["armature:ia=0.5,0.2"])
    play = simgap.simulate(arm, TARGET, controller="pd", kp=KP, kv=KV, effects=["armature:ia=0.5,0.2", "backlash:width=0.03,0.03"])
    assert simgap.compare(play, rotor).overall > 1e-5
    with pytest.raises(SimulationError, match="backlash"):
        simgap.simulate(arm, TARGET, controller="pd", kp=KP, kv=KV, effects=["armature:ia=0.5,0.2", "backlash:width=0.03,0.03"], integrator="adaptive")


def test_replay_of_the_commanded_torque_reproduces_the_run_open_loop(paper_run: Run) -> None:
    replayed = simgap.simulate(simgap.Model.paper_arm(), paper_run, controller="replay")
    assert simgap.compare(replayed, paper_run).overall < 1e-3


def test_l2_is_the_rms_over_time() -> None:
    t = np.linspace(0.0, 2.0, 2001)
    x = np.stack([np.sin(np.pi * t), np.ones_like(t)], axis=1)
    # mean of sin² over whole periods is 1/2, of 1 is 1
    assert simgap.l2(t, x) == pytest.approx(np.sqrt(1.5), rel=1e-6)
    assert simgap.l2(t, x[:, 1]) == pytest.approx(1.0)
    assert simgap.l2(t.tolist(), x.tolist()) == simgap.l2(t, x)
    with pytest.raises(DimensionError, match="x: expected shape"):
        simgap.l2(t, x[:-1])


def test_l2_tracking_matches_l2_of_the_error(paper_run: Run) -> None:
    report = simgap.l2_tracking(paper_run)
    assert report.overall == pytest.approx(simgap.l2(paper_run.t, paper_run.q_ref - paper_run.q), rel=1e-12)
    late = simgap.l2_tracking(paper_run, window=(2.0, 3.0))
    assert late.span == (2.0, 3.0) and late.overall < report.overall


@pytest.mark.parametrize("name", ["run.mcap", "run.csv", "run.csv.gz"])
def test_log_round_trip(paper_run: Run, tmp_path: Path, name: str) -> None:
    path = tmp_path / name
    simgap.write_log(paper_run, path)
    back = simgap.read_log(path)
    assert back.joints == paper_run.joints
    np.testing.assert_allclose(back.t, paper_run.t, atol=1e-9)
    np.testing.assert_allclose(back.q, paper_run.q, atol=1e-12)
    np.testing.assert_allclose(back.tau, paper_run.tau, atol=1e-12)
    assert back.experiment is not None and back.experiment["controller"] == "pd"
    reordered = simgap.read_log(str(path), joints=["elbow", "shoulder"])
    np.testing.assert_array_equal(reordered.q, back.q[:, ::-1])


def test_run_from_arrays(tmp_path: Path) -> None:
    t = np.arange(5) * 0.01
    q = np.zeros((5, 2))
    run = Run(["a", "b"], t, q, q, experiment={"controller": "pd", "joints": "a,b", "kp": "1,2", "kv": "3,4", "sample_period": "0.01"})
    assert run.dof == 2 and run.tau is None and run.q_ref is None and run.duration == pytest.approx(0.04)
    assert run.experiment is not None and run.experiment["kp"].startswith("1")
    with pytest.raises(DimensionError, match=r"qd: expected shape \(5, 2\)"):
        Run(["a", "b"], t, q, q[:4])
    with pytest.raises(LogError):
        Run(["a", "b"], t[::-1], q, q)
    with pytest.raises(LogError, match="experiment"):
        Run(["a", "b"], t, q, q, experiment={"controller": "pid"})


def test_log_errors_name_the_file(tmp_path: Path, paper_run: Run) -> None:
    missing = tmp_path / "absent.mcap"
    with pytest.raises(LogError, match="absent.mcap"):
        simgap.read_log(missing)
    with pytest.raises(LogError, match="unknown log format"):
        simgap.read_log(tmp_path / "run.txt")
    garbage = tmp_path / "garbage.mcap"
    garbage.write_bytes(b"not an mcap file")
    with pytest.raises(LogError, match="garbage.mcap"):
        simgap.read_log(garbage)
    other = Run(["x", "y"], paper_run.t, paper_run.q, paper_run.qd)
    with pytest.raises(LogError, match="joint 'shoulder'"):
        simgap.compare(paper_run, other)


def test_simulation_errors() -> None:
    arm = simgap.Model.paper_arm()
    with pytest.raises(SimulationError, match="diverged"):
        simgap.simulate(arm, TARGET, controller="pd", kp=[1e9, 1e9], kv=[0, 0], duration=0.5)
    with pytest.raises(SimulationError, match="unknown effect 'magic'"):
        simgap.simulate(arm, TARGET, controller="pd", kp=KP, kv=KV, effects=["magic:x=1"])
    with pytest.raises(SimulationError, match="sample_period"):
        simgap.simulate(arm, TARGET, controller="pd", kp=KP, kv=KV, sample_period=-1.0)
    with pytest.raises(SimulationError, match="controller"):
        simgap.simulate(arm, TARGET, kp=KP, kv=KV)
    with pytest.raises(DimensionError, match="kp: expected 2, got 3"):
        simgap.simulate(arm, TARGET, controller="pd", kp=[1, 2, 3], kv=KV)
    with pytest.raises(DimensionError, match="reference: expected 2, got 1"):
        simgap.simulate(arm, [0.1], controller="pd", kp=KP, kv=KV)


# Impossible parameters, the words the library refuses them with (the CLI prints the same), and
# the keyword arguments that ask for them. Before the ranges were checked in the library, the
# first two ran for minutes (3e12 samples; 1e9 RK4 steps per sample).
IMPOSSIBLE = [
    ({"sample_period": 1e-12}, "invalid sample_period: 1e-12 s is out of range; expected 1e-6 ≤ sample_period ≤ 1 s"),
    ({"substeps": 1_000_000_000}, "invalid substeps: 1e9 is out of range; expected 1 ≤ substeps ≤ 10000"),
    ({"duration": 86401.0}, "invalid duration: 86401 s is out of range; expected 0 < duration ≤ 86400 s"),
    ({"duration": 0.0}, "invalid duration: 0 s is out of range; expected 0 < duration ≤ 86400 s"),
    ({"duration": 1000.0, "substeps": 5000}, "integration steps; expected at most 1e9"),
    ({"noise_std": -1.0}, "invalid noise_std: -1 rad is out of range; expected 0 ≤ noise_std ≤ 1 rad"),
    ({"coulomb_width": float("nan")}, "invalid coulomb_width"),
    # a day at 400 Hz is 3.5e7 samples: more than a Run in memory may hold
    ({"duration": 86400.0}, "a run held in memory has at most 1e7"),
]


@pytest.mark.parametrize(("kwargs", "words"), IMPOSSIBLE, ids=[next(iter(k)) + "-" + str(i) for i, (k, _) in enumerate(IMPOSSIBLE)])
def test_simulate_refuses_impossible_ranges_at_once(kwargs: dict[str, float], words: str) -> None:
    arm = simgap.Model.paper_arm()
    start = time.monotonic()
    with pytest.raises(SimulationError) as e:
        simgap.simulate(arm, TARGET, controller="pd", kp=KP, kv=KV, **kwargs)
    assert words in str(e.value)
    # refused before anything is simulated (a hang guard, not a speed target: these ran for minutes)
    assert time.monotonic() - start < 5.0


def test_simulate_refuses_with_the_words_of_the_cli() -> None:
    binary = Path(__file__).resolve().parents[2] / "target" / "release" / "simgap"
    if not binary.is_file():
        pytest.skip(f"{binary} is not built")
    import subprocess

    arm = simgap.Model.paper_arm()
    for args, kwargs in [(["--sample-period", "1e-12"], {"sample_period": 1e-12}), (["--substeps", "1000000000"], {"substeps": 1_000_000_000})]:
        cli = subprocess.run([str(binary), "simulate", *args], capture_output=True, text=True, timeout=60)
        assert cli.returncode == 1
        with pytest.raises(SimulationError) as e:
            simgap.simulate(arm, TARGET, controller="pd", kp=KP, kv=KV, **kwargs)
        assert str(e.value) in cli.stderr, (str(e.value), cli.stderr)


def test_simulation_is_interrupted_by_ctrl_c() -> None:
    arm = simgap.Model.paper_arm()
    timer = threading.Timer(0.2, _thread.interrupt_main)
    t0 = time.perf_counter()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            # 9.6e6 samples: within the 1e7 a Run in memory may hold, seconds to simulate
            simgap.simulate(arm, TARGET, controller="pd", kp=KP, kv=KV, duration=24_000.0)
            time.sleep(2.0)
    finally:
        timer.cancel()
    assert time.perf_counter() - t0 < 2.0
