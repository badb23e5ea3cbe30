"""Pinocchio 4.1 as a peer oracle for `simgap terms` on real URDFs.

For the paper arm, UR5 and the Panda (chain to `panda_hand`, fingers locked at zero in both
libraries), 1000 random states go through `simgap terms --states` in both formulations and are
compared, mapped by joint name, with Pinocchio:

- H with `crba` (upper triangle, symmetrised),
- C q̇ with `nonLinearEffects − computeGeneralizedGravity`,
- C with `computeCoriolisMatrix`, which is the Christoffel C (checked here by finite differences
  of `crba`, as is ours),
- g with `computeGeneralizedGravity`,
- Ḣ with `C_pin + C_pinᵀ`, and the simplified C with `½ (C_pin + C_pinᵀ)`,

all to 1e-9 relative to the norm of the reference matrix (or vector scale).

Needs `SIMGAP_BIN` (the release `simgap` binary; `make test` sets it), `pinocchio` and
`example-robot-data` (UR5 and Panda; the paper arm runs without it).
"""

from __future__ import annotations

import csv
import importlib.metadata
import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio", reason="pinocchio is not importable: `make venv` installs pin==4.1.0")

ROOT = Path(__file__).resolve().parents[2]
PAPER_ARM = ROOT / "crates" / "simgap-core" / "models" / "paper_arm.urdf"
COUNT = 1000
RTOL = 1e-9

# name -> (path inside the example-robot-data robots dir or None, tip link, joints locked at zero)
ROBOTS = {
    "paper_arm": (None, None, []),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", None, []),
    "panda": ("panda_description/urdf/panda.urdf", "panda_hand", ["panda_finger_joint1", "panda_finger_joint2"]),
}


def simgap_bin() -> Path:
    env = os.environ.get("SIMGAP_BIN")
    path = Path(env) if env else ROOT / "target" / "release" / "simgap"
    if not path.exists():
        pytest.skip(f"simgap binary not found at {path}: set SIMGAP_BIN (make test does) or cargo build --release --bin simgap")
    return path


def robots_dir() -> Path | None:
    """example-robot-data's robots directory: SIMGAP_ROBOTS_DIR, the module, or the cmeel wheel."""
    env = os.environ.get("SIMGAP_ROBOTS_DIR")
    if env:
        return Path(env) if Path(env).is_dir() else None
    try:
        import example_robot_data  # type: ignore[import-not-found]

        return Path(example_robot_data.getModelPath("ur_description/urdf/ur5_robot.urdf"))
    except ImportError:
        pass
    try:
        p = Path(str(importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data/robots")))
        return p if p.is_dir() else None
    except importlib.metadata.PackageNotFoundError:
        return None


def urdf_path(robot: str) -> Path:
    rel = ROBOTS[robot][0]
    if rel is None:
        return PAPER_ARM
    rdir = robots_dir()
    if rdir is None or not (rdir / rel).exists():
        pytest.skip(f"{robot}: example-robot-data not found (make venv, or set SIMGAP_ROBOTS_DIR)")
    return rdir / rel


class Case:
    """One robot: the Pinocchio model, random states, and simgap's output in both formulations."""

    def __init__(self, robot: str, tmp: Path):
        _, tip, locked = ROBOTS[robot]
        urdf = urdf_path(robot)
        model = pin.buildModelFromUrdf(str(urdf))
        if locked:
            model = pin.buildReducedModel(model, [model.getJointId(j) for j in locked], pin.neutral(model))
        model.gravity.linear = np.array([0.0, 0.0, -9.81])
        assert all(model.joints[j].nq == 1 for j in range(1, model.njoints)), "only one-angle joints expected"
        self.model, self.data = model, model.createData()
        self.names = [model.names[j] for j in range(1, model.njoints)]
        self.iv = {model.names[j]: model.joints[j].idx_v for j in range(1, model.njoints)}
        # random states, written with our CSV header in Pinocchio's order (simgap maps by name)
        rng = np.random.default_rng(20240601 + len(robot))
        self.q = rng.uniform(-np.pi, np.pi, (COUNT, model.nv))
        self.qd = rng.uniform(-2.0, 2.0, (COUNT, model.nv))
        states = tmp / f"{robot}_states.csv"
        with states.open("w", newline="") as f:
            w = csv.writer(f)
            w.writerow([f"q_{n}" for n in self.names] + [f"qd_{n}" for n in self.names])
            for q, qd in zip(self.q, self.qd):
                w.writerow([repr(float(x)) for x in np.concatenate([q, qd])])
        self.out = {}
        for formulation in ("euler-lagrange", "simplified"):
            cmd = [str(simgap_bin()), "terms", "--urdf", str(urdf), "--states", str(states), "--formulation", formulation]
            if tip:
                cmd += ["--tip", tip]
            run = subprocess.run(cmd, capture_output=True, text=True)
            assert run.returncode == 0, f"{' '.join(cmd)} failed:\n{run.stderr}"
            lines = [json.loads(line) for line in run.stdout.splitlines() if line.strip()]
            assert len(lines) == COUNT, f"{robot}: expected {COUNT} JSON lines, got {len(lines)}"
            self.out[formulation] = lines
        # permutation from simgap's joint order to Pinocchio's velocity indices, by name
        joints = self.out["euler-lagrange"][0]["joints"]
        assert sorted(joints) == sorted(self.names), f"{robot}: simgap joints {joints} vs Pinocchio {self.names}"
        self.perm = np.array([self.iv[n] for n in joints])

    def pin_terms(self, k: int):
        """Pinocchio's H (symmetrised), C, g and C q̇ at state k, in simgap's joint order."""
        m, d, p = self.model, self.data, self.perm
        q, v = self.q[k], self.qd[k]
        h = pin.crba(m, d, q).copy()
        h = np.triu(h) + np.triu(h, 1).T
        c = pin.computeCoriolisMatrix(m, d, q, v).copy()
        g = pin.computeGeneralizedGravity(m, d, q).copy()
        cqd = pin.nonLinearEffects(m, d, q, v).copy() - g
        return h[np.ix_(p, p)], c[np.ix_(p, p)], g[p], cqd[p]

    def state(self, k: int):
        """q and q̇ of state k in simgap's order."""
        return self.q[k][self.perm], self.qd[k][self.perm]


_CASES: dict[str, Case] = {}


@pytest.fixture(scope="module", params=list(ROBOTS))
def case(request, tmp_path_factory) -> Case:
    robot = request.param
    if robot not in _CASES:
        _CASES[robot] = Case(robot, tmp_path_factory.mktemp(robot))
    return _CASES[robot]


def rel_err(a: np.ndarray, b: np.ndarray, scale: float | None = None) -> float:
    s = scale if scale is not None else np.linalg.norm(b)
    return float(np.linalg.norm(np.asarray(a) - b) / max(s, 1e-300))


def christoffel_fd(case: Case, k: int, eps: float = 1e-5) -> np.ndarray:
    """C_ij = Σ_k ½(∂H_ij/∂q_k + ∂H_ik/∂q_j − ∂H_jk/∂q_i) q̇_k from central differences of crba
    (Pinocchio's order)."""
    m, d = case.model, case.data
    q, v = case.q[k], case.qd[k]
    n = m.nv
    dh = np.zeros((n, n, n))  # dh[l] = ∂H/∂q_l
    for l in range(n):
        e = np.zeros(n)
        e[l] = eps
        hp = pin.crba(m, d, q + e).copy()
        hm = pin.crba(m, d, q - e).copy()
        hp, hm = np.triu(hp) + np.triu(hp, 1).T, np.triu(hm) + np.triu(hm, 1).T
        dh[l] = (hp - hm) / (2 * eps)
    # dh[l, i, j] = ∂H_ij/∂q_l
    return 0.5 * (np.einsum("lij,l->ij", dh, v) + np.einsum("jik,k->ij", dh, v) - np.einsum("ijk,k->ij", dh, v))


def test_mass_matrix_equals_pinocchio_crba(case):
    worst = max(rel_err(line["H"], case.pin_terms(k)[0]) for k, line in enumerate(case.out["euler-lagrange"]))
    assert worst < RTOL, f"H: worst relative error {worst:.2e}"


def test_gravity_torques_equal_pinocchio_generalized_gravity(case):
    worst = 0.0
    for k, line in enumerate(case.out["euler-lagrange"]):
        g = case.pin_terms(k)[2]
        worst = max(worst, rel_err(line["g"], g, scale=max(np.linalg.norm(g), 1.0)))
    assert worst < RTOL, f"g: worst relative error {worst:.2e}"


def test_coriolis_times_qd_equals_nonlinear_effects_minus_gravity(case):
    worst = 0.0
    for k, line in enumerate(case.out["euler-lagrange"]):
        _, c_pin, _, cqd = case.pin_terms(k)
        _, qd = case.state(k)
        scale = np.linalg.norm(c_pin) * np.linalg.norm(qd)
        worst = max(worst, rel_err(np.array(line["C"]) @ qd, cqd, scale=scale))
    assert worst < RTOL, f"C qd: worst relative error {worst:.2e}"


def test_coriolis_matrix_is_christoffel_like_pinocchio(case):
    """Both C are checked against Christoffel symbols from finite differences of H on a few
    states; then ours must equal Pinocchio's to 1e-9 on all states. Should they differ, the
    difference N is reported with its properties (N q̇ = 0, N skew) and which one is Christoffel."""
    for k in range(5):
        c_fd = christoffel_fd(case, k)[np.ix_(case.perm, case.perm)]
        c_ours = np.array(case.out["euler-lagrange"][k]["C"])
        c_pin = case.pin_terms(k)[1]
        scale = max(np.linalg.norm(c_fd), 1e-12)
        assert rel_err(c_ours, c_fd, scale) < 1e-6, f"simgap C is not Christoffel at state {k}: {rel_err(c_ours, c_fd, scale):.2e}"
        pin_is_christoffel = rel_err(c_pin, c_fd, scale) < 1e-6
    worst, k_worst = 0.0, 0
    for k, line in enumerate(case.out["euler-lagrange"]):
        e = rel_err(line["C"], case.pin_terms(k)[1])
        if e > worst:
            worst, k_worst = e, k
    if worst >= RTOL:
        c_ours = np.array(case.out["euler-lagrange"][k_worst]["C"])
        c_pin = case.pin_terms(k_worst)[1]
        nmat = c_ours - c_pin
        _, qd = case.state(k_worst)
        pytest.fail(
            f"C differs from computeCoriolisMatrix by {worst:.2e} (state {k_worst}); N = C_simgap - C_pin has "
            f"|N qd|/|N||qd| = {np.linalg.norm(nmat @ qd) / (np.linalg.norm(nmat) * np.linalg.norm(qd)):.2e}, "
            f"|N + N^T|/|N| = {np.linalg.norm(nmat + nmat.T) / np.linalg.norm(nmat):.2e}; "
            f"Pinocchio's C is Christoffel by finite differences: {pin_is_christoffel}"
        )


def test_hdot_equals_pinocchio_c_plus_c_transpose(case):
    worst = 0.0
    for k, line in enumerate(case.out["euler-lagrange"]):
        c_pin = case.pin_terms(k)[1]
        hdot = c_pin + c_pin.T
        worst = max(worst, rel_err(line["Hdot"], hdot, scale=max(np.linalg.norm(hdot), 2 * np.linalg.norm(c_pin))))
    assert worst < RTOL, f"Hdot: worst relative error {worst:.2e}"


def test_simplified_c_is_half_of_pinocchio_hdot(case):
    worst = 0.0
    for k, line in enumerate(case.out["simplified"]):
        c_pin = case.pin_terms(k)[1]
        half_hdot = 0.5 * (c_pin + c_pin.T)
        worst = max(worst, rel_err(line["C"], half_hdot, scale=max(np.linalg.norm(half_hdot), np.linalg.norm(c_pin))))
    assert worst < RTOL, f"simplified C: worst relative error {worst:.2e}"
