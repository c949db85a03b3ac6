"""Forward dynamics, the inverse mass matrix and the derivative kernels of every generated arm against Pinocchio's
Python API (``aba``, ``computeMinverse``, ``computeRNEADerivatives``, ``computeABADerivatives``) on the same random
states, and the batch shapes and layouts.

Pinocchio gets the arm through dynid's URDF export, as in test_kernels.py. Tolerance: the issue's 1e-9 relative (max
|error| / max |reference|); both sides are analytic evaluations in double precision (dynid: unrolled LDLᵀ and
forward-mode differentiation of Newton–Euler; Pinocchio: ABA and its analytic derivatives), which agree to about
cond(M)·ε ≈ 1e-12, while a wrong sign, frame, row or column is off by O(1)."""

from __future__ import annotations

import dynid
import numpy as np
import pinocchio as pin
import pytest
from conftest import pin_q, plausible_params, random_states, rel_err

TOL = 1e-9
SAMPLES = 20


def full(upper: np.ndarray) -> np.ndarray:
    """The symmetric matrix of which Pinocchio filled the upper triangle."""
    u = np.triu(upper)
    return u + np.triu(u, 1).T


@pytest.fixture(scope="module", params=dynid.arms())
def case(request):
    arm = dynid.Arm(request.param)
    rng = np.random.default_rng(41 + sum(map(ord, request.param)))
    p = plausible_params(arm.dof, rng)
    model = pin.buildModelFromXML(arm.to_urdf(p))
    q, dq, ddq = random_states(arm, SAMPLES, rng)
    tau = arm.inverse_dynamics(q, dq, ddq, p) + rng.uniform(-3.0, 3.0, (SAMPLES, arm.dof))
    return arm, p, model, model.createData(), q, dq, ddq, tau


def test_forward_dynamics_and_inverse_mass_matrix_equal_pinocchio(case):
    arm, p, model, data, q, dq, _, tau = case
    acc = arm.forward_dynamics(q, dq, tau, p)
    inv = arm.inverse_mass_matrix(q, p)
    assert acc.shape == (SAMPLES, arm.dof) and inv.shape == (SAMPLES, arm.dof, arm.dof)
    for k in range(SAMPLES):
        qk = pin_q(model, q[k])
        assert rel_err(acc[k], pin.aba(model, data, qk, dq[k], tau[k])) < TOL, f"{arm.name} aba, sample {k}"
        assert rel_err(inv[k], full(pin.computeMinverse(model, data, qk))) < TOL, f"{arm.name} Minv, {k}"


def test_inverse_dynamics_derivatives_equal_pinocchio(case):
    arm, p, model, data, q, dq, ddq, _ = case
    dtau_dq, dtau_dv = arm.inverse_dynamics_derivatives(q, dq, ddq, p)
    assert dtau_dq.shape == dtau_dv.shape == (SAMPLES, arm.dof, arm.dof)
    for k in range(SAMPLES):
        want_q, want_v, _ = pin.computeRNEADerivatives(model, data, pin_q(model, q[k]), dq[k], ddq[k])
        assert rel_err(dtau_dq[k], want_q) < TOL, f"{arm.name} dtau/dq, sample {k}"
        assert rel_err(dtau_dv[k], want_v) < TOL, f"{arm.name} dtau/dv, sample {k}"


def test_forward_dynamics_derivatives_equal_pinocchio(case):
    arm, p, model, data, q, dq, _, tau = case
    da_dq, da_dv, minv = arm.forward_dynamics_derivatives(q, dq, tau, p)
    for k in range(SAMPLES):
        want_q, want_v, want_tau = pin.computeABADerivatives(model, data, pin_q(model, q[k]), dq[k], tau[k])
        assert rel_err(da_dq[k], want_q) < TOL, f"{arm.name} dddq/dq, sample {k}"
        assert rel_err(da_dv[k], want_v) < TOL, f"{arm.name} dddq/dv, sample {k}"
        assert rel_err(minv[k], full(want_tau)) < TOL, f"{arm.name} dddq/dtau, sample {k}"


def test_one_sample_gives_unbatched_blocks_equal_to_the_batch_rows(case):
    arm, p, _, _, q, dq, ddq, tau = case
    one = arm.forward_dynamics_derivatives(q[0], dq[0], tau[0], p)
    batch = arm.forward_dynamics_derivatives(q[:5], dq[:5], tau[:5], p)
    for a, b in zip(one, batch):
        assert a.shape == (arm.dof, arm.dof)
        np.testing.assert_allclose(a, b[0], rtol=1e-13, atol=1e-13)
    d = arm.inverse_dynamics_derivatives(q[1], dq[1], ddq[1], p)
    assert len(d) == 2 and all(x.shape == (arm.dof, arm.dof) for x in d)
    # q̈ = FD(τ) inverts τ = ID(q̈), through the batched (lane) kernels.
    acc = arm.forward_dynamics(q, dq, arm.inverse_dynamics(q, dq, ddq, p), p)
    assert rel_err(acc, ddq) < TOL
