"""Partial derivatives of inverse and forward dynamics, by forward-mode differentiation.

``∂τ/∂q`` and ``∂τ/∂q̇`` are the Newton–Euler recursion's expression graph differentiated in
forward mode (CasADi's ``jtimes``: one directional derivative per joint variable, each a sweep over
the same graph with the tangents of the inputs as seeds), so they cost a small multiple of the
recursion itself per column, and every intermediate (the links' velocities, their tangents) is
shared between columns by the emitter's common-subexpression elimination. Nothing is
differentiated as a flat expression.

A revolute joint's angle reaches the kernels only through its cosine and sine (kernel inputs), so
its tangent seeds them: ``d cᵢ = −sᵢ``, ``d sᵢ = cᵢ``; a prismatic joint's variable is seeded
directly.

Forward dynamics ``q̈ = M⁻¹ (τ − h)``: ``∂q̈/∂x = −M⁻¹ ∂τ/∂x`` at ``(q, q̇, q̈)`` for ``x = q, q̇``
(differentiate ``τ = ID(q, q̇, FD(q, q̇, τ))``), and ``∂q̈/∂τ = M⁻¹`` — Carpentier and Mansard's
identity, which Pinocchio's ``computeABADerivatives`` uses too.
"""

from __future__ import annotations

import casadi as ca

from .algebra import Scalar
from .kinematics import Symbols


def joint_tangents(sym: Symbols) -> tuple[ca.SX, ca.SX]:
    """The inputs ``(trig, q, q̇)`` stacked, and the seed matrix whose column ``i`` is their tangent
    along ``qᵢ`` (columns ``0 … n−1``) and along ``q̇ᵢ`` (columns ``n … 2n−1``)."""
    n = sym.dof
    inputs = ca.vertcat(sym.trig, sym.q, sym.dq)
    seeds = ca.SX.zeros(4 * n, 2 * n)
    for i in range(n):
        seeds[2 * i, i] = -sym.trig[2 * i + 1]
        seeds[2 * i + 1, i] = sym.trig[2 * i]
        seeds[2 * n + i, i] = 1.0
        seeds[3 * n + i, n + i] = 1.0
    return inputs, seeds


def inverse_dynamics_jacobians(sym: Symbols, tau: list[Scalar]) -> tuple[ca.SX, ca.SX]:
    """``(∂τ/∂q, ∂τ/∂q̇)``, each ``n × n`` (rows: joint forces, columns: joint variables), of the
    inverse-dynamics expressions ``tau`` (in ``trig, q, q̇, q̈, θ``) at fixed ``q̈``."""
    n = sym.dof
    inputs, seeds = joint_tangents(sym)
    J = ca.jtimes(ca.vertcat(*[ca.SX(t) for t in tau]), inputs, seeds)
    return J[:, :n], J[:, n:]


def inverse_dynamics_jvp(sym: Symbols, tau: list[Scalar]) -> tuple[ca.SX, ca.SX]:
    """``(d, ∂τ/∂x · d)``: the directional derivative of the inverse-dynamics expressions ``tau``
    along ``d = (δq, δq̇)`` (``2n`` symbols), at fixed ``q̈`` — one forward sweep for any direction,
    so that a kernel evaluating it on four unit directions at once (one per lane) gives four
    columns of ``(∂τ/∂q, ∂τ/∂q̇)``."""
    n = sym.dof
    inputs, seeds = joint_tangents(sym)
    d = ca.SX.sym("d", 2 * n)
    return d, ca.jtimes(ca.vertcat(*[ca.SX(t) for t in tau]), inputs, ca.mtimes(seeds, d))
