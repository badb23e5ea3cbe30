"""The exception tree, and every class raised by a real bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import simgap
from simgap import DimensionError, DynamicsError, FitError, LogError, SimgapError, SimulationError, UrdfError


def test_exception_tree() -> None:
    for cls in (UrdfError, LogError, DimensionError, DynamicsError, SimulationError, FitError):
        assert issubclass(cls, SimgapError)
        assert cls.__module__ == "simgap"
        assert cls.__doc__
    assert issubclass(SimgapError, Exception) and not issubclass(SimgapError, ValueError)
    assert issubclass(DimensionError, ValueError)
    assert issubclass(DynamicsError, ValueError)
    assert simgap.DimensionError is simgap._simgap.DimensionError


INERTIAL = '<inertial><origin xyz="0 0 -0.5"/><mass value="{mass}"/><inertia ixx="{ixx}" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial>'


def link(name: str, mass: str = "1", ixx: str = "0.1", inertial: bool = True) -> str:
    return f'<link name="{name}">{INERTIAL.format(mass=mass, ixx=ixx) if inertial else ""}</link>'


def joint(name: str, parent: str, child: str, kind: str = "revolute", axis: str = "0 1 0") -> str:
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="0 0 -1"/><axis xyz="{axis}"/><limit lower="-1" upper="1" effort="10" velocity="2"/></joint>'
    )


def robot(*parts: str) -> str:
    return '<?xml version="1.0"?>\n<robot name="bad">' + "".join(parts) + "</robot>"


GOOD = robot('<link name="base"/>', link("l1"), joint("j1", "base", "l1"), link("l2"), joint("j2", "l1", "l2"))

# one bad URDF per simgap_core::Error variant reachable from a file
BAD_URDFS = {
    "malformed": ("<robot name='x'><link name='a'>", "malformed URDF"),
    "duplicate_link": (robot('<link name="base"/>', link("l1"), link("l1"), joint("j1", "base", "l1")), "link 'l1' is defined more than once"),
    "duplicate_joint": (
        robot('<link name="base"/>', link("l1"), link("l2"), joint("j1", "base", "l1"), joint("j1", "l1", "l2")),
        "joint 'j1' is defined more than once",
    ),
    "missing_link": (robot('<link name="base"/>', link("l1"), joint("j1", "base", "nowhere")), "'nowhere', which is not defined"),
    "loop": (
        robot('<link name="base"/>', link("l1"), link("l2"), joint("j1", "base", "l1"), joint("j2", "l1", "l2"), joint("j3", "l2", "l1")),
        "expected a tree",
    ),
    "two_roots": (robot('<link name="base"/>', link("l1"), joint("j1", "base", "l1"), link("stray")), "expected exactly one root link"),
    "not_serial": (
        robot('<link name="base"/>', link("l1"), link("l2"), joint("j1", "base", "l1"), joint("j2", "base", "l2")),
        "the chain is not serial",
    ),
    "no_movable_joint": (robot('<link name="base"/>', link("l1"), joint("j1", "base", "l1", kind="fixed")), "no movable joint"),
    "unsupported_joint": (robot('<link name="base"/>', link("l1"), joint("j1", "base", "l1", kind="floating")), "unsupported type 'floating'"),
    "zero_axis": (robot('<link name="base"/>', link("l1"), joint("j1", "base", "l1", axis="0 0 0")), "zero-length axis"),
    "non_finite": (robot('<link name="base"/>', link("l1", mass="nan"), joint("j1", "base", "l1")), "non-finite value"),
    "negative_mass": (robot('<link name="base"/>', link("l1", mass="-1"), joint("j1", "base", "l1")), "expected mass >= 0"),
    "non_physical_inertia": (robot('<link name="base"/>', link("l1", ixx="-1"), joint("j1", "base", "l1")), "non-physical inertia"),
    "massless": (robot('<link name="base"/>', link("l1", inertial=False), joint("j1", "base", "l1")), "massless"),
}


@pytest.mark.parametrize("case", sorted(BAD_URDFS))
def test_every_urdf_error_is_a_urdf_error_naming_the_file(tmp_path: Path, case: str) -> None:
    text, fragment = BAD_URDFS[case]
    path = tmp_path / f"{case}.urdf"
    path.write_text(text)
    with pytest.raises(UrdfError, match=fragment) as info:
        simgap.Model.from_urdf(path)
    assert str(path) in str(info.value)


def test_unknown_tip_is_a_urdf_error(tmp_path: Path) -> None:
    path = tmp_path / "good.urdf"
    path.write_text(GOOD)
    assert simgap.Model.from_urdf(path).dof == 2
    assert simgap.Model.from_urdf(str(path), tip="l1").joint_names == ["j1"]
    with pytest.raises(UrdfError, match="tip link 'nope' is not defined") as info:
        simgap.Model.from_urdf(path, tip="nope")
    assert str(path) in str(info.value)


def test_missing_file_is_a_urdf_error_naming_the_file(tmp_path: Path) -> None:
    path = tmp_path / "absent.urdf"
    with pytest.raises(UrdfError, match="cannot read file") as info:
        simgap.Model.from_urdf(path)
    assert str(path) in str(info.value)


def test_wrong_length_is_a_dimension_error_naming_the_argument(paper_arm: simgap.Model) -> None:
    with pytest.raises(DimensionError, match=r"^q: expected 2, got 3"):
        paper_arm.mass_matrix([1.0, 2.0, 3.0])
    with pytest.raises(DimensionError, match=r"^qd: expected 2, got 3"):
        paper_arm.coriolis_matrix([1.0, 2.0], [1.0, 2.0, 3.0])
    with pytest.raises(DimensionError, match=r"^qdd: expected 2, got 1"):
        paper_arm.inverse_dynamics(np.zeros((4, 2)), np.zeros((4, 2)), np.zeros((4, 1)))
    with pytest.raises(DimensionError, match=r"^q: expected 2, got 3"):
        paper_arm.mass_matrix(np.zeros((10, 3)))
    with pytest.raises(ValueError, match=r"^tau: expected 2, got 3"):
        paper_arm.forward_dynamics([0, 0], [0, 0], [0, 0, 0])


def test_mismatched_batches_and_ranks_are_dimension_errors(paper_arm: simgap.Model) -> None:
    with pytest.raises(DimensionError, match=r"qd: expected shape \(10, 2\) like q, got \(9, 2\)"):
        paper_arm.coriolis_matrix(np.zeros((10, 2)), np.zeros((9, 2)))
    with pytest.raises(DimensionError, match=r"qd: expected shape \(10, 2\) like q, got \(2,\)"):
        paper_arm.coriolis_matrix(np.zeros((10, 2)), np.zeros(2))
    with pytest.raises(DimensionError, match=r"q: expected shape \(2,\) or \(N, 2\), got \(2, 2, 2\)"):
        paper_arm.mass_matrix(np.zeros((2, 2, 2)))
    with pytest.raises(DimensionError, match=r"q: expected shape \(2,\) or \(N, 2\), got \(\)"):
        paper_arm.mass_matrix(1.0)
    with pytest.raises(DimensionError, match=r"gravity: expected 3, got 2"):
        paper_arm.gravity = [0.0, -9.81]


def test_non_finite_forward_dynamics_input_is_a_dynamics_error(paper_arm: simgap.Model) -> None:
    with pytest.raises(DynamicsError, match=r"qd: expected finite values, got nan at qd\[1\]"):
        paper_arm.forward_dynamics([0.0, 0.0], [0.0, np.nan], [0.0, 0.0])
    tau = np.zeros((5, 2))
    tau[3, 0] = np.inf
    with pytest.raises(DynamicsError, match=r"tau: expected finite values, got inf at tau\[3, 0\]"):
        paper_arm.forward_dynamics(np.zeros((5, 2)), np.zeros((5, 2)), tau)
    model = simgap.Model.paper_arm()
    with pytest.raises(DynamicsError, match="gravity: expected finite values"):
        model.gravity = [0.0, 0.0, np.nan]


def test_singular_mass_matrix_is_a_dynamics_error_not_a_panic(tmp_path: Path) -> None:
    # the tip link is massless and has no inertia: H is singular
    path = tmp_path / "massless_tip.urdf"
    path.write_text(robot('<link name="base"/>', link("l1"), joint("j1", "base", "l1"), link("l2", inertial=False), joint("j2", "l1", "l2")))
    model = simgap.Model.from_urdf(path)
    assert any("massless" in w for w in model.warnings)
    with pytest.raises(DynamicsError, match="not positive definite"):
        model.forward_dynamics([0.0, 0.0], [0.0, 0.0], [0.0, 0.0])
    with pytest.raises(DynamicsError, match="state 0: .*not positive definite"):
        model.forward_dynamics(np.zeros((3, 2)), np.zeros((3, 2)), np.zeros((3, 2)))
    # the model stays usable
    assert model.mass_matrix([0.0, 0.0]).shape == (2, 2)


def test_nan_positions_give_nan_not_an_error(paper_arm: simgap.Model) -> None:
    # only forward dynamics needs finite inputs; the other terms propagate NaN like numpy
    assert np.isnan(paper_arm.mass_matrix([np.nan, 0.0])).any()


def test_uncovertible_input_is_a_value_error(paper_arm: simgap.Model) -> None:
    with pytest.raises(ValueError):
        paper_arm.mass_matrix("not a number")
    with pytest.raises(ValueError):
        paper_arm.mass_matrix([[1.0, 2.0], [3.0]])
