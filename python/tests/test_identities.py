"""Physics identities re-checked through the bindings (the Rust tests check them in depth)."""

from __future__ import annotations

import numpy as np

import simgap
from conftest import random_states

N = 200


def scale(x: np.ndarray) -> float:
    return max(1.0, float(np.abs(x).max()))


def test_paper_arm_h11_matches_the_papers_closed_form(paper_arm: simgap.Model) -> None:
    q = np.array([0.3, -0.7])
    h = paper_arm.mass_matrix(q)
    assert abs(h[0, 0] - (2.3515719820 + 0.167616 * np.cos(q[1]))) < 1e-9
    g = paper_arm.gravity_torques(q)
    assert abs(g[0] - (38.46581442 * np.sin(q[0]) + 1.8270144 * np.sin(q[0] + q[1]))) < 1e-6


def test_mass_matrix_is_symmetric_positive_definite(model: simgap.Model) -> None:
    q, _, _ = random_states(model, N, seed=1)
    h = model.mass_matrix(q)
    assert h.shape == (N, model.dof, model.dof)
    np.testing.assert_allclose(h, h.transpose(0, 2, 1), atol=1e-12 * scale(h))
    assert (np.linalg.eigvalsh(h) > 0).all()


def test_hdot_minus_2c_is_skew_symmetric(model: simgap.Model) -> None:
    q, qd, _ = random_states(model, N, seed=2)
    n = model.mass_matrix_derivative(q, qd) - 2 * model.coriolis_matrix(q, qd, "euler_lagrange")
    np.testing.assert_allclose(n + n.transpose(0, 2, 1), 0.0, atol=1e-10 * scale(n))


def test_simplified_c_is_half_hdot(model: simgap.Model) -> None:
    q, qd, _ = random_states(model, N, seed=3)
    hdot = model.mass_matrix_derivative(q, qd)
    np.testing.assert_allclose(model.coriolis_matrix(q, qd, "simplified"), hdot / 2, atol=1e-12 * scale(hdot))


def test_coriolis_times_qd_plus_gravity_equals_inverse_dynamics_at_rest_acceleration(model: simgap.Model) -> None:
    q, qd, _ = random_states(model, N, seed=4)
    c = model.coriolis_matrix(q, qd)
    g = model.gravity_torques(q)
    tau = model.inverse_dynamics(q, qd, np.zeros_like(qd))
    np.testing.assert_allclose(np.einsum("nij,nj->ni", c, qd) + g, tau, atol=1e-9 * scale(tau))
    np.testing.assert_allclose(model.coriolis_torques(q, qd) + g, tau, atol=1e-9 * scale(tau))
    np.testing.assert_allclose(model.bias_torques(q, qd), tau, atol=1e-9 * scale(tau))


def test_simplified_coriolis_torques_are_half_hdot_qd(model: simgap.Model) -> None:
    q, qd, _ = random_states(model, N, seed=5)
    hdot = model.mass_matrix_derivative(q, qd)
    expected = np.einsum("nij,nj->ni", hdot, qd) / 2
    np.testing.assert_allclose(model.coriolis_torques(q, qd, "simplified"), expected, atol=1e-10 * scale(expected))


def test_gravity_torques_equal_inverse_dynamics_at_rest(model: simgap.Model) -> None:
    q, _, _ = random_states(model, N, seed=6)
    zero = np.zeros_like(q)
    np.testing.assert_allclose(model.gravity_torques(q), model.inverse_dynamics(q, zero, zero), atol=1e-10)


def test_inverse_dynamics_is_h_qdd_plus_c_qd_plus_g(model: simgap.Model) -> None:
    q, qd, qdd = random_states(model, N, seed=7)
    h, c, g = model.dynamics_terms(q, qd)
    tau = model.inverse_dynamics(q, qd, qdd)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", h, qdd) + np.einsum("nij,nj->ni", c, qd) + g, tau, atol=1e-9 * scale(tau))


def test_forward_dynamics_inverts_inverse_dynamics(model: simgap.Model) -> None:
    q, qd, qdd = random_states(model, N, seed=8)
    tau = model.inverse_dynamics(q, qd, qdd)
    np.testing.assert_allclose(model.forward_dynamics(q, qd, tau), qdd, atol=1e-8)


def test_forward_dynamics_with_simplified_c_uses_half_hdot(model: simgap.Model) -> None:
    q, qd, qdd = random_states(model, N, seed=9)
    h, c, g = model.dynamics_terms(q, qd, formulation="simplified")
    tau = np.einsum("nij,nj->ni", h, qdd) + np.einsum("nij,nj->ni", c, qd) + g
    np.testing.assert_allclose(model.forward_dynamics(q, qd, tau, formulation="simplified"), qdd, atol=1e-8)


def test_kinetic_energy_is_half_qd_h_qd(model: simgap.Model) -> None:
    q, qd, _ = random_states(model, N, seed=10)
    h = model.mass_matrix(q)
    np.testing.assert_allclose(model.kinetic_energy(q, qd), 0.5 * np.einsum("ni,nij,nj->n", qd, h, qd), rtol=1e-12)


def test_gravity_is_gradient_of_potential_energy(model: simgap.Model) -> None:
    q, _, _ = random_states(model, 20, seed=11)
    eps = 1e-6
    for row in q:
        grad = [(model.potential_energy(row + eps * e) - model.potential_energy(row - eps * e)) / (2 * eps) for e in np.eye(model.dof)]
        np.testing.assert_allclose(grad, model.gravity_torques(row), atol=1e-6 * scale(model.gravity_torques(row)))


def test_dynamics_terms_equal_the_separate_calls(model: simgap.Model) -> None:
    q, qd, _ = random_states(model, N, seed=12)
    for formulation in ("euler_lagrange", "simplified"):
        h, c, g = model.dynamics_terms(q, qd, formulation)
        np.testing.assert_allclose(h, model.mass_matrix(q), rtol=1e-14, atol=1e-14)
        np.testing.assert_allclose(c, model.coriolis_matrix(q, qd, formulation), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(g, model.gravity_torques(q), rtol=1e-12, atol=1e-12)


def test_gravity_setter_scales_gravity_torques(paper_arm: simgap.Model) -> None:
    model = simgap.Model.paper_arm()
    q = [0.4, 0.2]
    g0 = model.gravity_torques(q)
    model.gravity = np.array([0, 0, -2 * 9.81])
    np.testing.assert_allclose(model.gravity, [0, 0, -19.62])
    np.testing.assert_allclose(model.gravity_torques(q), 2 * g0, rtol=1e-12)
    # the shared fixture is another object and is untouched
    np.testing.assert_allclose(paper_arm.gravity, [0, 0, -9.81])
