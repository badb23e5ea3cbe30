"""Shared fixtures: models, seeded states, and the example-robot-data URDFs Pinocchio ships."""

from __future__ import annotations

import os
import site
from pathlib import Path

import numpy as np
import pytest

import simgap


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "slow: a test that takes a minute or more (it still runs in `make test`; deselect with -m 'not slow')")


def robots_dir() -> Path | None:
    """example-robot-data's `robots` folder (pip package `example-robot-data`), if installed."""
    candidates = []
    if "EXAMPLE_ROBOT_DATA_DIR" in os.environ:
        candidates.append(Path(os.environ["EXAMPLE_ROBOT_DATA_DIR"]))
    for base in [*site.getsitepackages(), site.getusersitepackages()]:
        candidates.append(Path(base) / "cmeel.prefix" / "share" / "example-robot-data" / "robots")
    try:
        import example_robot_data  # type: ignore[import-not-found]

        candidates.append(Path(example_robot_data.getModelPath("panda_description/urdf/panda.urdf")) / "robots")
    except Exception:  # noqa: BLE001 - optional module, any failure means "not there"
        pass
    return next((c for c in candidates if (c / "panda_description").is_dir()), None)


def robot_urdf(relative: str) -> Path:
    root = robots_dir()
    if root is None:
        pytest.skip("example-robot-data is not installed (pip install example-robot-data)")
    return root / relative


@pytest.fixture(scope="session")
def panda_urdf() -> Path:
    return robot_urdf("panda_description/urdf/panda.urdf")


@pytest.fixture(scope="session")
def ur5_urdf() -> Path:
    return robot_urdf("ur_description/urdf/ur5_robot.urdf")


@pytest.fixture(scope="session")
def panda(panda_urdf: Path) -> simgap.Model:
    """The Panda arm with its fingers locked at 0 (merged into the hand)."""
    return simgap.Model.from_urdf(panda_urdf, tip="panda_hand")


@pytest.fixture(scope="session")
def paper_arm() -> simgap.Model:
    return simgap.Model.paper_arm()


def random_states(model: simgap.Model, n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`n` seeded (q, qd, qdd) rows: q uniform in [-pi, pi], qd and qdd standard normal."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, size=(n, model.dof))
    qd = rng.normal(size=(n, model.dof))
    qdd = rng.normal(size=(n, model.dof))
    return q, qd, qdd


MODELS = ["paper_arm", "panda"]


@pytest.fixture(params=MODELS)
def model(request: pytest.FixtureRequest) -> simgap.Model:
    return request.getfixturevalue(request.param)
