"""Agreement with Pinocchio 4.1 through the bindings, on UR5 and Panda (fingers locked at 0).

1000 seeded random states per robot; H, C q̇, C (Euler–Lagrange) and g agree to 1e-9 relative
(to the largest entry of Pinocchio's result, or 1 if smaller).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import simgap
from conftest import random_states

pin = pytest.importorskip("pinocchio")

N = 1000
RTOL = 1e-9


def pinocchio_model(urdf: Path, locked: list[str]):  # noqa: ANN201
    full = pin.buildModelFromUrdf(str(urdf))
    if not locked:
        return full
    ids = [full.getJointId(name) for name in locked]
    return pin.buildReducedModel(full, ids, np.zeros(full.nq))


def pinocchio_terms(model, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, ...]:  # noqa: ANN001
    """H, C, C q̇ and g for every row, one Pinocchio call each."""
    data = model.createData()
    hs, cs, cqds, gs = [], [], [], []
    for qk, qdk in zip(q, qd):
        h = pin.crba(model, data, qk).copy()
        hs.append(np.triu(h) + np.triu(h, 1).T)  # crba fills the upper triangle
        cs.append(pin.computeCoriolisMatrix(model, data, qk, qdk).copy())
        g = pin.computeGeneralizedGravity(model, data, qk).copy()
        gs.append(g)
        cqds.append(pin.rnea(model, data, qk, qdk, np.zeros(model.nv)) - g)
    return tuple(np.array(x) for x in (hs, cs, cqds, gs))


def assert_close(actual: np.ndarray, expected: np.ndarray, what: str) -> None:
    # relative to each state's largest entry
    axes = tuple(range(1, expected.ndim))
    scale = np.maximum(1.0, np.abs(expected).max(axis=axes, keepdims=True))
    err = np.abs(actual - expected) / scale
    worst = np.unravel_index(err.argmax(), err.shape)
    assert err.max() <= RTOL, f"{what}: relative error {err.max():.3e} at {worst}: {actual[worst]} vs {expected[worst]}"


@pytest.mark.parametrize(
    ("robot", "tip", "locked"),
    [
        ("ur5", None, []),
        ("panda", "panda_hand", ["panda_finger_joint1", "panda_finger_joint2"]),
    ],
)
def test_terms_agree_with_pinocchio(robot: str, tip: str | None, locked: list[str], request: pytest.FixtureRequest) -> None:
    urdf: Path = request.getfixturevalue(f"{robot}_urdf")
    ours = simgap.Model.from_urdf(urdf, tip=tip)
    theirs = pinocchio_model(urdf, locked)
    assert ours.joint_names == list(theirs.names)[1:]
    np.testing.assert_array_equal(ours.gravity, theirs.gravity.linear)

    q, qd, _ = random_states(ours, N, seed=2024)
    h_pin, c_pin, cqd_pin, g_pin = pinocchio_terms(theirs, q, qd)
    h, c, g = ours.dynamics_terms(q, qd, "euler_lagrange")

    assert_close(h, h_pin, "H")
    assert_close(c, c_pin, "C")
    assert_close(ours.coriolis_torques(q, qd), cqd_pin, "C qd")
    assert_close(np.einsum("nij,nj->ni", c, qd), cqd_pin, "C @ qd")
    assert_close(g, g_pin, "g")
    assert_close(ours.mass_matrix(q), h_pin, "mass_matrix")
    assert_close(ours.gravity_torques(q), g_pin, "gravity_torques")


def test_panda_fingers_are_merged_into_the_hand(panda: simgap.Model) -> None:
    assert panda.dof == 7
    assert panda.joint_names == [f"panda_joint{i}" for i in range(1, 8)]
    assert any("panda_finger_joint1" in w for w in panda.warnings)
