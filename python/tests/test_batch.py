"""Batches equal one-by-one evaluation (to 1e-12 relative: batches run several states per SIMD
register); inputs of any array-like kind; C-ordered outputs."""

from __future__ import annotations

import _thread
import threading
import time

import numpy as np
import pytest

import simgap
from conftest import random_states

# method name -> how many joint vectors it takes, and whether it takes a formulation
METHODS = {
    "mass_matrix": (1, False),
    "gravity_torques": (1, False),
    "potential_energy": (1, False),
    "coriolis_matrix": (2, True),
    "coriolis_torques": (2, True),
    "bias_torques": (2, True),
    "mass_matrix_derivative": (2, False),
    "kinetic_energy": (2, False),
    "inverse_dynamics": (3, False),
    "forward_dynamics": (3, True),
}


def assert_same(batch_row: np.ndarray, single: np.ndarray | float) -> None:
    """Equal to 1e-12 relative to the largest entry (the batch kernels round differently)."""
    scale = max(float(np.abs(single).max()), 1e-300)
    np.testing.assert_allclose(batch_row, single, rtol=0, atol=1e-12 * scale)


def call(model: simgap.Model, name: str, states: tuple[np.ndarray, ...], formulation: str | None = None):  # noqa: ANN201
    nargs, takes_formulation = METHODS[name]
    args = states[:nargs]
    if takes_formulation and formulation is not None:
        return getattr(model, name)(*args, formulation=formulation)
    return getattr(model, name)(*args)


@pytest.mark.parametrize("name", sorted(METHODS))
@pytest.mark.parametrize("n", [1, 7, 500])
def test_batch_equals_one_by_one(model: simgap.Model, name: str, n: int) -> None:
    states = random_states(model, n, seed=n)
    batch = call(model, name, states)
    assert batch.shape[0] == n
    for k in range(n):
        single = call(model, name, tuple(s[k] for s in states))
        assert_same(batch[k], single)


@pytest.mark.parametrize("n", [1, 3, 1000])
def test_dynamics_terms_batch_equals_one_by_one(model: simgap.Model, n: int) -> None:
    q, qd, _ = random_states(model, n, seed=n)
    for formulation in ("euler_lagrange", "euler-lagrange", "simplified"):
        hb, cb, gb = model.dynamics_terms(q, qd, formulation)
        assert hb.shape == cb.shape == (n, model.dof, model.dof) and gb.shape == (n, model.dof)
        for k in range(0, n, max(1, n // 50)):
            h, c, g = model.dynamics_terms(q[k], qd[k], formulation)
            assert_same(hb[k], h)
            assert_same(cb[k], c)
            assert_same(gb[k], g)


def test_shapes_of_single_state_results(paper_arm: simgap.Model) -> None:
    q, qd = [0.1, 0.2], [0.3, 0.4]
    assert paper_arm.mass_matrix(q).shape == (2, 2)
    assert paper_arm.coriolis_matrix(q, qd).shape == (2, 2)
    assert paper_arm.gravity_torques(q).shape == (2,)
    assert isinstance(paper_arm.kinetic_energy(q, qd), float)
    assert isinstance(paper_arm.potential_energy(q), float)
    assert paper_arm.kinetic_energy([q], [qd]).shape == (1,)
    assert paper_arm.mass_matrix([q]).shape == (1, 2, 2)
    assert paper_arm.mass_matrix(np.zeros((0, 2))).shape == (0, 2, 2)


def test_outputs_are_c_ordered_float64_with_row_i_equation_i(panda: simgap.Model) -> None:
    q, qd, _ = random_states(panda, 10, seed=3)
    c = panda.coriolis_matrix(q, qd)
    assert c.dtype == np.float64 and c.flags["C_CONTIGUOUS"] and c.flags["OWNDATA"] or c.base is not None
    # row i of C times qd is the Coriolis torque of joint i
    np.testing.assert_allclose(c @ qd[..., None], panda.coriolis_torques(q, qd)[..., None], atol=1e-10)
    assert not np.allclose(c, c.transpose(0, 2, 1))


def test_lists_tuples_int_and_fortran_arrays_are_accepted(paper_arm: simgap.Model) -> None:
    expected = paper_arm.mass_matrix(np.array([1.0, 2.0]))
    for q in ([1, 2], (1.0, 2.0), np.array([1, 2], dtype=np.int32), np.array([1.0, 2.0], dtype=np.float32)):
        np.testing.assert_array_equal(paper_arm.mass_matrix(q), expected)
    q, qd, _ = random_states(paper_arm, 50, seed=4)
    reference = paper_arm.coriolis_matrix(q, qd)
    np.testing.assert_array_equal(paper_arm.coriolis_matrix(np.asfortranarray(q), qd), reference)
    np.testing.assert_array_equal(paper_arm.coriolis_matrix(q.tolist(), qd[:, :].copy(order="F")), reference)
    # a strided view
    wide = np.repeat(q, 2, axis=1)
    np.testing.assert_array_equal(paper_arm.coriolis_matrix(wide[:, ::2], qd), reference)


def test_formulation_accepts_both_spellings(paper_arm: simgap.Model) -> None:
    q, qd = [0.1, 0.2], [0.3, 0.4]
    np.testing.assert_array_equal(paper_arm.coriolis_matrix(q, qd, "euler-lagrange"), paper_arm.coriolis_matrix(q, qd, "euler_lagrange"))
    np.testing.assert_array_equal(paper_arm.coriolis_matrix(q, qd), paper_arm.coriolis_matrix(q, qd, formulation="euler_lagrange"))
    with pytest.raises(ValueError, match="formulation: expected 'euler_lagrange' or 'simplified', got 'newton'"):
        paper_arm.coriolis_matrix(q, qd, "newton")  # type: ignore[arg-type]


def test_batch_releases_the_gil(panda: simgap.Model) -> None:
    # a Python thread keeps counting while a long batch runs
    q, qd, _ = random_states(panda, 200_000, seed=5)
    ticks = 0
    done = threading.Event()

    def count() -> None:
        nonlocal ticks
        while not done.is_set():
            ticks += 1
            time.sleep(0.001)

    thread = threading.Thread(target=count)
    thread.start()
    t0 = time.perf_counter()
    panda.dynamics_terms(q, qd)
    elapsed = time.perf_counter() - t0
    done.set()
    thread.join()
    assert ticks >= min(5, int(elapsed / 0.002)), (ticks, elapsed)


def test_batch_is_interrupted_by_ctrl_c(panda: simgap.Model) -> None:
    q, qd, qdd = random_states(panda, 1_000_000, seed=6)
    t0 = time.perf_counter()
    full = None
    timer = threading.Timer(0.05, _thread.interrupt_main)
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            full = panda.inverse_dynamics(q, qd, qdd)
            # finished before the timer fired: wait for it, so it cannot hit another test
            time.sleep(1.0)
    finally:
        timer.cancel()
    assert full is None, "the batch finished before the interrupt; make it longer"
    assert time.perf_counter() - t0 < 5.0


def test_large_batch_across_chunks_and_threads_equals_one_by_one(panda: simgap.Model) -> None:
    # more states than one chunk between signal checks, split over threads, not a multiple of 8
    q, qd, qdd = random_states(panda, 20_003, seed=9)
    h = panda.mass_matrix(q)
    hb, cb, gb = panda.dynamics_terms(q, qd, "simplified")
    tau = panda.inverse_dynamics(q, qd, qdd)
    for k in (0, 7, 8, 8162, 8163, 8164, 16_000, 20_001, 20_002):
        assert_same(h[k], panda.mass_matrix(q[k]))
        h1, c1, g1 = panda.dynamics_terms(q[k], qd[k], "simplified")
        assert_same(hb[k], h1)
        assert_same(cb[k], c1)
        assert_same(gb[k], g1)
        assert_same(tau[k], panda.inverse_dynamics(q[k], qd[k], qdd[k]))
