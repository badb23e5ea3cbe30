"""The documented install runs the fleet command: a fresh venv with only ``./python[fleet]`` (no
test requirements) writes every output of ``python -m simgap.fleet``, the HTML report
included (it needs matplotlib, which the extra once lacked).

Slow (marked ``slow``): it creates the venv and installs the package with its extra, once per
session; the Rust extension comes from the cached build in ``target/``, the dependencies from
pip's cache. 77 s on our loaded 2-core machine."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("pandas")

from simgap.fleet.synthetic import make_synthetic_fleet  # noqa: E402

PACKAGE = Path(__file__).resolve().parents[1]  # python/
NO_NETWORK = ("Failed to establish a new connection", "Temporary failure in name resolution", "Network is unreachable")


@pytest.fixture(scope="session")
def fleet_venv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh venv with only ``./python[fleet]`` installed; its Python."""
    venv = tmp_path_factory.mktemp("fleet-venv") / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=120)
    python = venv / "bin" / "python"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    proc = subprocess.run([str(python), "-m", "pip", "install", "--quiet", "--disable-pip-version-check", f"{PACKAGE}[fleet]"], capture_output=True, text=True, timeout=900, env=env)
    if proc.returncode != 0 and any(m in proc.stderr for m in NO_NETWORK):
        pytest.skip(f"no package index reachable: {proc.stderr.strip().splitlines()[-1]}")
    assert proc.returncode == 0, proc.stderr
    return python


@pytest.mark.slow
def test_the_fleet_extra_alone_runs_the_fleet_command(fleet_venv: Path, tmp_path: Path) -> None:
    # only the extra: none of the test requirements
    probe = subprocess.run([str(fleet_venv), "-c", "import importlib.util as u; print([m for m in ('pytest', 'pin', 'mcap') if u.find_spec(m)])"], capture_output=True, text=True, timeout=60)
    assert probe.stdout.strip() == "[]", probe.stdout + probe.stderr
    synthetic = make_synthetic_fleet(tmp_path / "logs", robots=2, days=1, payload_from_day=1)
    out = tmp_path / "out"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")} | {"RAYON_NUM_THREADS": "1"}
    proc = subprocess.run([str(fleet_venv), "-m", "simgap.fleet", str(tmp_path / "logs"), "--urdf", str(synthetic.urdf), "--workers", "1", "--no-progress", "--out", str(out)], capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert {p.name for p in out.iterdir()} == {"fleet.parquet", "tasks.csv", "drift.csv", "outliers.csv", "flagged.csv", "fleet.html", "reports"}
    assert (out / "fleet.html").read_text().startswith("<!DOCTYPE html>") and "2 of 2 robot-days diagnosed" in proc.stdout
