"""Kinetic energy T, potential energy V and the Lagrange equations, linear in the inertial parameters.

For link j with parameters p_j = (XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M) about its frame origin,
with v_j the origin velocity and w_j the angular velocity (both in frame j), s_j = (MX, MY, MZ):

    T_j = 1/2 M v_j.v_j + v_j.(w_j x s_j) + 1/2 w_j.I_j w_j,      V_j = -g.(M p_0j + R_0j s_j)

tau = d/dt dL/d(dq) - dL/dq with L = T - V. The regressor column of p_k is the same expression with L
replaced by its coefficient of p_k. CasADi's algorithmic differentiation produces the equations; this is
the derivation the Newton-Euler form in ``newton_euler.py`` is checked against at generation time.
"""

from __future__ import annotations

import casadi as ca

from .dh import DhTable, cos_sin


def _inertia(p: ca.SX) -> ca.SX:
    xx, xy, xz, yy, yz, zz = (p[k] for k in range(6))
    return ca.vertcat(ca.horzcat(xx, xy, xz), ca.horzcat(xy, yy, yz), ca.horzcat(xz, yz, zz))


def energies(arm: DhTable, q: ca.SX, dq: ca.SX, p: ca.SX) -> tuple[ca.SX, ca.SX]:
    """T(q, dq, p) and V(q, p) as CasADi expressions."""
    g = ca.DM(list(arm.gravity))
    R0 = ca.SX.eye(3)
    p0 = ca.SX.zeros(3)
    w = ca.SX.zeros(3)
    v = ca.SX.zeros(3)
    T = ca.SX(0)
    V = ca.SX(0)
    z = ca.DM([0, 0, 1])
    for i, jt in enumerate(arm.joints):
        ca_, sa = cos_sin(jt.alpha)
        if jt.kind == "revolute":
            th, d = q[i] + jt.theta, jt.d
        else:
            th, d = jt.theta, q[i] + jt.d
        c, s = ca.cos(th), ca.sin(th)
        R = ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(ca_ * s, ca_ * c, -sa), ca.horzcat(sa * s, sa * c, ca_))
        pos = ca.vertcat(jt.a, -sa * d, ca_ * d)
        # velocities of the new frame, expressed in it
        v = R.T @ (v + ca.cross(w, pos))
        w = R.T @ w
        if jt.kind == "revolute":
            w = w + dq[i] * z
        else:
            v = v + dq[i] * z
        p0 = p0 + R0 @ pos
        R0 = R0 @ R
        pj = p[10 * i : 10 * i + 10]
        s_j = pj[6:9]
        T += 0.5 * pj[9] * ca.dot(v, v) + ca.dot(v, ca.cross(w, s_j)) + 0.5 * ca.dot(w, _inertia(pj) @ w)
        V += -ca.dot(g, pj[9] * p0 + R0 @ s_j)
    return T, V


def lagrange_function(arm: DhTable) -> ca.Function:
    """CasADi function (q, dq, ddq) -> full regressor Y (n x 10n) from the Lagrange equations."""
    n = arm.dof
    q, dq, ddq = ca.SX.sym("q", n), ca.SX.sym("dq", n), ca.SX.sym("ddq", n)
    p = ca.SX.sym("p", 10 * n)
    T, V = energies(arm, q, dq, p)
    L = T - V
    dL_ddq = ca.gradient(L, dq)
    tau = ca.jacobian(dL_ddq, q) @ dq + ca.jacobian(dL_ddq, dq) @ ddq - ca.gradient(L, q)
    Y = ca.jacobian(tau, p)
    return ca.Function("lagrange_regressor", [q, dq, ddq], [Y])
