"""A position-controlled servo's signals in a Run built from numpy arrays: kept, checked, and
read back, and a servo log written as CSV diagnosed from Python."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import simgap
from simgap import DimensionError, LogError, Run

PENDULUM = Path(__file__).resolve().parents[2] / "crates" / "simgap-core" / "models" / "pendulum.urdf"


def servo_arrays(n: int = 400) -> dict[str, np.ndarray]:
    t = np.arange(n) * 0.005
    q = 0.3 * np.sin(t - 0.1)
    return {
        "t": t,
        "q": q[:, None],
        "qd": (0.3 * np.cos(t - 0.1))[:, None],
        "q_ref": (0.3 * np.sin(t))[:, None],
        "duty": np.clip(2.0 * (0.3 * np.sin(t) - q), -1, 1)[:, None],
        "torque_enable": (t < 1.5).astype(float)[:, None],
        "voltage": np.full(n, 7.4),
        "temperature": np.full((n, 1), 30.0),
    }


def test_a_servo_run_keeps_its_duty_enable_voltage_and_temperature() -> None:
    a = servo_arrays()
    run = Run(["hinge"], a["t"], a["q"], a["qd"], q_ref=a["q_ref"], duty=a["duty"], torque_enable=a["torque_enable"], voltage=a["voltage"], temperature=a["temperature"])
    np.testing.assert_array_equal(run.duty, a["duty"])
    np.testing.assert_array_equal(run.torque_enable, a["torque_enable"])
    np.testing.assert_array_equal(run.voltage, a["voltage"])
    np.testing.assert_array_equal(run.temperature, a["temperature"])
    assert run.tau is None, "a servo logs no torque"
    plain = Run(["hinge"], a["t"], a["q"], a["qd"])
    assert plain.duty is None and plain.voltage is None


def test_bad_servo_signals_are_refused_naming_them() -> None:
    a = servo_arrays()
    duty = a["duty"].copy()
    duty[7, 0] = 1.5
    with pytest.raises(LogError, match=r"duty of joint 'hinge' is 1.5 .*sample 7.*\[-1, 1\]"):
        Run(["hinge"], a["t"], a["q"], a["qd"], q_ref=a["q_ref"], duty=duty)
    enable = a["torque_enable"].copy()
    enable[3, 0] = 0.5
    with pytest.raises(LogError, match="torque_enable of joint 'hinge' is 0.5"):
        Run(["hinge"], a["t"], a["q"], a["qd"], torque_enable=enable)
    with pytest.raises(DimensionError, match="voltage: expected shape"):
        Run(["hinge"], a["t"], a["q"], a["qd"], voltage=a["voltage"][:10])


def test_a_servo_log_without_its_duty_gain_is_refused_by_the_diagnosis(tmp_path: Path) -> None:
    a = servo_arrays()
    csv = tmp_path / "servo.csv"
    rows = np.column_stack([a["t"], a["q"][:, 0], a["qd"][:, 0], a["q_ref"][:, 0], a["duty"][:, 0], a["torque_enable"][:, 0]])
    np.savetxt(csv, rows, delimiter=",", header="time,q_hinge,qd_hinge,q_ref_hinge,duty_hinge,torque_enable_hinge", comments="")
    (tmp_path / "servo.experiment.json").write_text(json.dumps({"controller": "servo", "joints": "hinge", "supply_voltage": "12"}))
    with pytest.raises(simgap.SimgapError, match="duty_gain"):
        simgap.diagnose(simgap.Model.from_urdf(PENDULUM), [str(csv)], progress=False)
    # the same with the load friction rising at rest asked for (the CLI's --load-stribeck-friction)
    with pytest.raises(simgap.SimgapError, match="duty_gain"):
        simgap.diagnose(simgap.Model.from_urdf(PENDULUM), [str(csv)], progress=False, load_stribeck_friction=True)


@pytest.mark.parametrize("name", ["servo.csv", "servo.mcap"])
def test_a_servo_run_written_and_read_back_keeps_its_drive_signals(tmp_path: Path, name: str) -> None:
    a = servo_arrays()
    experiment = {"controller": "servo", "joints": "hinge", "duty_gain": "2", "supply_voltage": "7.4", "sample_period": "0.005"}
    run = Run(["hinge"], a["t"], a["q"], a["qd"], q_ref=a["q_ref"], duty=a["duty"], torque_enable=a["torque_enable"], voltage=a["voltage"], temperature=a["temperature"], experiment=experiment)
    simgap.write_log(run, tmp_path / name)
    back = simgap.read_log(tmp_path / name)
    np.testing.assert_array_equal(back.duty, a["duty"])
    np.testing.assert_array_equal(back.torque_enable, a["torque_enable"])
    np.testing.assert_array_equal(back.voltage, a["voltage"])
    np.testing.assert_array_equal(back.temperature, a["temperature"])
    np.testing.assert_array_equal(back.q_ref, a["q_ref"])


def test_a_servo_simulated_from_its_log_logs_its_duty_enable_and_voltage() -> None:
    # a servo log with its motor constants: the simulator drives the servo with the logged goal
    # and torque enable (off from 1.5 s), and the run it returns holds what a servo logs
    a = servo_arrays()
    experiment = {"controller": "servo", "joints": "hinge", "duty_gain": "2", "supply_voltage": "12", "kt": "1.5", "R": "1.5", "sample_period": "0.005"}
    log = Run(["hinge"], a["t"], a["q"], a["qd"], q_ref=a["q_ref"], torque_enable=a["torque_enable"], experiment=experiment)
    run = simgap.simulate(simgap.Model.from_urdf(PENDULUM), log, effects=["viscous_friction:b=0.5"])
    assert run.experiment["controller"] == "servo"
    on = a["torque_enable"][:, 0] > 0.5
    np.testing.assert_array_equal(run.torque_enable, a["torque_enable"])
    np.testing.assert_array_equal(run.voltage, np.full(len(a["t"]), 12.0))
    # the duty is the firmware's P law on the measured position while enabled, 0 while not
    expected = np.where(on, np.clip(2.0 * (run.q_ref[:, 0] - run.q[:, 0]), -1, 1), 0.0)
    np.testing.assert_allclose(run.duty[:, 0], expected, rtol=0, atol=1e-12)
    # and the command is its voltage part, (kt / R) V duty
    np.testing.assert_allclose(run.tau[:, 0], 1.5 / 1.5 * 12.0 * expected, rtol=1e-12, atol=1e-12)
    assert np.ptp(run.duty[on]) > 0.1 and not np.any(run.duty[~on])


def test_a_servo_is_simulated_from_an_experiment_without_a_log() -> None:
    # the sidecar's keys as a dict: the servo's constants, the sample period; a step goal
    experiment = {"controller": "servo", "joints": "hinge", "duty_gain": 2, "supply_voltage": 12, "kt": 1.5, "R": 1.5, "sample_period": 0.005}
    run = simgap.simulate(simgap.Model.from_urdf(PENDULUM), [0.6], experiment=experiment, duration=6.0, counts_per_rev=None)
    assert run.experiment["controller"] == "servo" and run.experiment["kt"] == "1.5"
    np.testing.assert_allclose(np.diff(run.t), 0.005)
    np.testing.assert_allclose(run.duty[:, 0], np.clip(2.0 * (0.6 - run.q[:, 0]), -1, 1), rtol=0, atol=1e-12)
    assert run.duty[0, 0] == 1.0 and np.all(run.torque_enable == 1.0) and np.all(run.voltage == 12.0)
    # at rest the drive holds the arm below the goal against gravity (m = 2 kg at l = 0.5 m):
    # duty (kt/R) V = 2 (0.6 − q) · 12 = m g l sin q
    q_end = run.q[-1, 0]
    assert abs(run.qd[-1, 0]) < 1e-2 and 0.3 < q_end < 0.6, (q_end, run.qd[-1, 0])
    assert abs(2.0 * (0.6 - q_end) * 12.0 - 2.0 * 9.81 * 0.5 * np.sin(q_end)) < 0.02
    # an experiment without the servo's constants is refused naming the key
    with pytest.raises(simgap.SimulationError, match="kt"):
        simgap.simulate(simgap.Model.from_urdf(PENDULUM), [0.6], experiment={k: v for k, v in experiment.items() if k not in ("kt", "R")})
