"""Every kernel of every generated arm against Pinocchio's Python API on the same random states.

Pinocchio gets the same arm through dynid's URDF export (links = the D-H frames, the parameters as inertials). The
tolerance is the issue's 1e-9 relative (max |error| / max |reference|): both sides evaluate the same quantities in
double precision by different algorithms, so they agree to ~1e-13; a wrong sign, frame or parameter order is off
by O(1)."""

from __future__ import annotations

import dynid
import numpy as np
import pinocchio as pin
import pytest
from conftest import pin_columns, pin_q, plausible_params, random_states, rel_err

TOL = 1e-9
SAMPLES = 40


@pytest.fixture(scope="module", params=dynid.arms())
def case(request):
    arm = dynid.Arm(request.param)
    rng = np.random.default_rng(sum(map(ord, request.param)))
    p = plausible_params(arm.dof, rng)
    model = pin.buildModelFromXML(arm.to_urdf(p))
    assert model.nv == arm.dof, f"pinocchio sees {model.nv} joints, dynid {arm.dof}"
    q, dq, ddq = random_states(arm, SAMPLES, rng)
    return arm, p, model, model.createData(), q, dq, ddq


def test_every_generated_arm_is_tested():
    assert set(dynid.arms()) >= {"planar2", "puma560", "scara", "panda"}
    assert all(dynid.Arm(a).generated for a in dynid.arms())


def test_regressor_and_base_regressor_equal_pinocchio(case):
    arm, p, model, data, q, dq, ddq = case
    y = arm.regressor(q, dq, ddq)  # one batched call (the lane kernels)
    yb = arm.base_regressor(q, dq, ddq)
    b = arm.base_map
    cols = pin_columns(arm.dof)
    assert y.shape == (SAMPLES, arm.dof, 10 * arm.dof) and yb.shape == (SAMPLES, arm.dof, arm.nb)
    for k in range(SAMPLES):
        y_pin = pin.computeJointTorqueRegressor(model, data, pin_q(model, q[k]), dq[k], ddq[k])[:, cols]
        assert rel_err(y[k], y_pin) < TOL, f"{arm.name} regressor, sample {k}"
        # Y = Yb·B: the base regressor times the base-parameter map is Pinocchio's full regressor.
        assert rel_err(yb[k] @ b, y_pin) < TOL, f"{arm.name} base regressor, sample {k}"
        assert rel_err(yb[k] @ arm.base_params(p), y_pin @ p) < TOL


def test_mass_matrix_bias_gravity_inverse_dynamics_equal_pinocchio(case):
    arm, p, model, data, q, dq, ddq = case
    m = arm.mass_matrix(q, p)
    h = arm.bias(q, dq, p)
    g = arm.gravity(q, p)
    tau = arm.inverse_dynamics(q, dq, ddq, p)
    for k in range(SAMPLES):
        qk = pin_q(model, q[k])
        m_pin = np.triu(pin.crba(model, data, qk))  # Pinocchio fills the upper triangle
        m_pin = m_pin + np.triu(m_pin, 1).T
        assert rel_err(m[k], m_pin) < TOL, f"{arm.name} mass matrix, sample {k}"
        assert rel_err(h[k], pin.nonLinearEffects(model, data, qk, dq[k])) < TOL, f"{arm.name} bias, sample {k}"
        assert rel_err(g[k], pin.computeGeneralizedGravity(model, data, qk)) < TOL, f"{arm.name} gravity {k}"
        assert rel_err(tau[k], pin.rnea(model, data, qk, dq[k], ddq[k])) < TOL, f"{arm.name} rnea, sample {k}"


def test_one_sample_equals_its_row_of_a_batch_bit_for_bit(case):
    """(n,) goes through the scalar kernel, (N, n) through the lanes (and the scalar tail): the same numbers."""
    arm, p, _, _, q, dq, ddq = case
    # Below, at and past a four-lane pack, an eight-lane pack (AVX-512 CPUs), and 8 + 4 + 1 (every form in one call).
    for n in (1, 3, 4, 7, 8, 13, SAMPLES):
        batch = arm.base_regressor(q[:n], dq[:n], ddq[:n])
        tau = arm.inverse_dynamics(q[:n], dq[:n], ddq[:n], p)
        for k in range(n):
            assert np.array_equal(batch[k], arm.base_regressor(q[k], dq[k], ddq[k]))
            assert np.array_equal(tau[k], arm.inverse_dynamics(q[k], dq[k], ddq[k], p))
    one_thread = arm.regressor(q, dq, ddq, threads=1)
    assert np.array_equal(one_thread, arm.regressor(q, dq, ddq))
    assert np.array_equal(one_thread, arm.regressor(q, dq, ddq, threads=2))


def test_any_memory_layout(case):
    arm, p, _, _, q, dq, ddq = case
    want = arm.inverse_dynamics(q, dq, ddq, p)
    fortran = np.asfortranarray(q)
    strided = np.repeat(dq, 2, axis=0)[::2]  # a non-contiguous view with the same values
    assert not strided.flags.c_contiguous
    assert np.array_equal(arm.inverse_dynamics(fortran, strided, ddq, p), want)
    assert np.array_equal(arm.inverse_dynamics(q, dq, ddq, p[::-1].copy()[::-1]), want)
    assert np.array_equal(arm.mass_matrix(q.tolist()[0], p), arm.mass_matrix(q[0], p))
