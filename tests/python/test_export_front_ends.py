"""The CLI and Python write the same corrected files for one diagnosis (docs/guide/export.md):
``simgap diagnose --export-urdf --export-mjcf`` and ``report.export_urdf`` / ``export_mjcf`` on
the same logs give byte-identical URDFs, MJCFs and sidecars, because both write from the
diagnosis alone (its report and the time step, passive joints and servo firmware it decided
from its prepared runs).

The logs are made so that the two front ends disagreed before they did: the held-out run is
sampled at 2 ms and the fit runs at 2.5 ms, and only the held-out run leaves the elbow
uncommanded. Python took the time step and the passive joints from the held-out runs alone
(timestep 0.002, the elbow without a motor), the CLI from every log (0.0025, the elbow driven).

Needs SIMGAP_BIN, as the other CLI tests.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import simgap

ROOT = Path(__file__).resolve().parents[2]
PAPER_ARM = ROOT / "crates" / "simgap-core" / "models" / "paper_arm.urdf"
KP = [64.72, 32.36]
KV = [48.54, 6.472]
HIDDEN = ["viscous_friction:b=2.288,0.175"]
FILES = ["corrected.urdf", "corrected.urdf.effects.json", "corrected.xml", "corrected.xml.effects.json"]


@pytest.fixture(scope="module")
def simgap_bin() -> str:
    binary = os.environ.get("SIMGAP_BIN")
    if not binary:
        if os.environ.get("CI"):
            pytest.fail("SIMGAP_BIN is not set: CI must build the CLI (cargo build --release --bin simgap) and set it")
        pytest.skip("SIMGAP_BIN is not set (cargo build --release --bin simgap; SIMGAP_BIN=$PWD/target/release/simgap)")
    return binary


def sine_reference(model: simgap.Model, duration: float, dt: float, freqs: tuple[float, float], amps: tuple[float, float], name: str) -> simgap.Run:
    """A smooth reference (q_ref, q̇_ref) from rest at q = 0, sampled every `dt` seconds."""
    t = np.arange(0.0, duration + 1e-9, dt)
    w = 2 * np.pi * np.asarray(freqs)
    a = np.asarray(amps)
    q = a * (1 - np.cos(np.outer(t, w)))
    qd = a * w * np.sin(np.outer(t, w))
    return simgap.Run(model.joint_names, t, q, qd, q_ref=q, qd_ref=qd, source=name)


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> tuple[list[Path], list[Path]]:
    """Two fit logs of the paper's arm under PD + gravity at 2.5 ms, and one held-out log at
    2 ms that replays a torque driving the shoulder only (the elbow swings uncommanded)."""
    model = simgap.Model.from_urdf(PAPER_ARM)
    out = tmp_path_factory.mktemp("logs")

    def closed_loop(duration: float, freqs: tuple[float, float], amps: tuple[float, float], name: str) -> simgap.Run:
        reference = sine_reference(model, duration, 0.0025, freqs, amps, name)
        return simgap.simulate(model, reference, controller="pd_gravity", kp=KP, kv=KV, effects=HIDDEN)

    fit = [closed_loop(3.0, (0.5, 0.8), (0.6, 0.8), "fit-a"), closed_loop(3.0, (0.3, 1.3), (0.9, 0.6), "fit-b")]
    # the held-out run: the shoulder's torque of a closed loop, the elbow's zero, replayed at 2 ms
    driven = simgap.simulate(model, sine_reference(model, 3.0, 0.002, (0.35, 1.1), (0.8, 0.5), "held"), controller="pd_gravity", kp=KP, kv=KV, sample_period=0.002, effects=HIDDEN)
    tau = np.array(driven.tau)
    tau[:, 1] = 0.0
    command = simgap.Run(model.joint_names, driven.t, driven.q, driven.qd, tau=tau, source="held")
    held = simgap.simulate(model, command, controller="replay", replay=command, sample_period=0.002, effects=HIDDEN)
    paths = []
    for run, name in [*zip(fit, ["fit-a.mcap", "fit-b.mcap"]), (held, "held.mcap")]:
        simgap.write_log(run, out / name)
        paths.append(out / name)
    return paths[:2], paths[2:]


def test_cli_and_python_write_byte_identical_corrected_files(logs: tuple[list[Path], list[Path]], simgap_bin: str, tmp_path: Path) -> None:
    fit, held = logs
    # the premise: the held-out log alone gives another time step and passive joint than every log
    assert simgap.read_log(held[0]).experiment["sample_period"] != simgap.read_log(fit[0]).experiment["sample_period"]
    assert np.all(simgap.read_log(held[0]).tau[:, 1] == 0.0) and np.any(simgap.read_log(fit[0]).tau[:, 1] != 0.0)
    # the CLI
    cli, py = tmp_path / "cli", tmp_path / "python"
    cli.mkdir()
    py.mkdir()
    args = [simgap_bin, "diagnose", "--urdf", str(PAPER_ARM)]
    args += [a for p in fit for a in ("--log", str(p))] + [a for p in held for a in ("--holdout", str(p))]
    args += ["--export-urdf", str(cli / "corrected.urdf"), "--export-mjcf", str(cli / "corrected.xml")]
    done = subprocess.run(args, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    # Python, on the same logs
    report = simgap.diagnose(simgap.Model.from_urdf(PAPER_ARM), [str(p) for p in fit], [str(p) for p in held], urdf=str(PAPER_ARM))
    report.export_urdf(py / "corrected.urdf")
    report.export_mjcf(py / "corrected.xml")
    # the same bytes, file by file
    for name in FILES:
        assert (py / name).read_bytes() == (cli / name).read_bytes(), f"{name} differs between the CLI and Python"
    # the time step and the motors are every log's: the fit logs' 2.5 ms, the elbow driven
    mjcf = (py / "corrected.xml").read_text()
    assert 'timestep="0.0025"' in mjcf, mjcf
    assert 'joint="elbow"' in mjcf and "is passive" not in (py / "corrected.xml.effects.json").read_text(), mjcf
