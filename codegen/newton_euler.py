"""Newton-Euler evaluation of the Lagrange equations: the structured form the kernels are emitted from.

The Lagrange equations of a serial chain (see ``lagrange.py``) equal the recursive Newton-Euler equations;
the generator derives both and checks they agree (``generate.py``). Newton-Euler is emitted because its
intermediate quantities (link velocities and accelerations) are shared by every regressor column, which is
what keeps the operation count low.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from .algebra import Scalar, Vec, add, cross, dot, is_const, is_zero, matTvec, matvec, mul, neg, sub, total, vadd
from .kinematics import LinkTransform

PARAMS = ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M")


@dataclass
class LinkMotion:
    w: Vec  # angular velocity of link i, in frame i
    wd: Vec  # angular acceleration, in frame i
    vd: Vec  # linear acceleration of the frame origin minus gravity, in frame i


def forward(tf: list[LinkTransform], dq: list[Scalar], ddq: list[Scalar], gravity: Vec) -> list[LinkMotion]:
    """Outward recursion; gravity enters as a base acceleration -g."""
    w: Vec = [0.0, 0.0, 0.0]
    wd: Vec = [0.0, 0.0, 0.0]
    vd: Vec = [neg(g) for g in gravity]
    out = []
    for i, t in enumerate(tf):
        # acceleration of origin i expressed in frame i-1, then rotated into frame i: U p, with the
        # U of link i-1 whose entries its force reads too (fewer products than wd x p + w x (w x p))
        U = u_matrix(w, wd)
        vd_prev = vadd(vd, [dot(U[r], t.p) for r in range(3)])
        vd_i = matTvec(t.R, vd_prev)
        w_rot = matTvec(t.R, w)
        wd_rot = matTvec(t.R, wd)
        if t.revolute:
            w = [w_rot[0], w_rot[1], add(w_rot[2], dq[i])]
            # (R^T w_{i-1}) x (dq_i z) + ddq_i z
            wd = [add(wd_rot[0], mul(w_rot[1], dq[i])), sub(wd_rot[1], mul(w_rot[0], dq[i])), add(wd_rot[2], ddq[i])]
        else:
            w, wd = w_rot, wd_rot
            # Coriolis 2 w x (dd z) and the joint acceleration along z
            cor = [mul(2.0, mul(w[1], dq[i])), neg(mul(2.0, mul(w[0], dq[i]))), 0.0]
            vd_i = [add(vd_i[0], cor[0]), add(vd_i[1], cor[1]), add(vd_i[2], ddq[i])]
        vd = vd_i
        out.append(LinkMotion(w, wd, vd))
    return out


def _products(w: Vec) -> tuple[Scalar, ...]:
    """``wx², wy², wz², wx·wy, wx·wz, wy·wz``."""
    wx, wy, wz = w
    return mul(wx, wx), mul(wy, wy), mul(wz, wz), mul(wx, wy), mul(wx, wz), mul(wy, wz)


def u_matrix(w: Vec, wd: Vec) -> list[list[Scalar]]:
    """``U = [wd]x + [w]x [w]x``: a point at ``s`` in the link accelerates by ``U s`` relative to the
    origin. Its columns are the force per unit first moment, and ``U p`` carries the acceleration to
    the next origin, so one set of entries (from the six products of ``w``) serves both."""
    xx, yy, zz, xy, xz, yz = _products(w)
    return [
        [neg(add(yy, zz)), sub(xy, wd[2]), add(xz, wd[1])],
        [add(xy, wd[2]), neg(add(xx, zz)), sub(yz, wd[0])],
        [sub(xz, wd[1]), add(yz, wd[0]), neg(add(xx, yy))],
    ]


def link_wrench_columns(m: LinkMotion) -> list[tuple[Vec, Vec]]:
    """(force, moment about the origin) in the link frame per unit parameter, in PARAMS order."""
    w, wd, vd = m.w, m.wd, m.vd
    z3: Vec = [0.0, 0.0, 0.0]
    xx, yy, zz, xy, xz, yz = _products(w)
    # Moments I*wd + w x (I w) for each unit inertia component
    n_inertia = [
        [wd[0], xz, neg(xy)],  # XX
        [sub(wd[1], xz), add(wd[0], yz), sub(xx, yy)],  # XY
        [add(wd[2], xy), sub(zz, xx), sub(wd[0], yz)],  # XZ
        [neg(yz), wd[1], xy],  # YY
        [sub(yy, zz), sub(wd[2], xy), add(wd[1], xz)],  # YZ
        [yz, neg(xz), wd[2]],  # ZZ
    ]
    cols: list[tuple[Vec, Vec]] = [(z3, n) for n in n_inertia]
    # First moments: f = wd x s + w x (w x s) = U s, n = s x vd for s = e_x, e_y, e_z
    U = u_matrix(w, wd)
    for k in range(3):
        s: Vec = [0.0, 0.0, 0.0]
        s[k] = 1.0
        cols.append(([U[r][k] for r in range(3)], cross(s, vd)))
    cols.append((list(vd), z3))  # M
    return cols


def transport(t: LinkTransform, f: Vec, n: Vec) -> tuple[Vec, Vec]:
    """Wrench (about origin i, frame i) expressed about origin i-1 in frame i-1."""
    f_prev = matvec(t.R, f)
    n_prev = vadd(matvec(t.R, n), cross(t.p, f_prev))
    return f_prev, n_prev


def regressor(tf: list[LinkTransform], motion: list[LinkMotion], wanted: set[int] | None = None) -> list[list[Scalar]]:
    """Full regressor Y[i][10*j + k] (zeros included); columns outside ``wanted`` are left 0.

    Joint i's force is a linear functional of each link wrench (f, n) at j >= i: tau_i = u.n + w.f, with u the
    axis of joint i and w = axis x (origin j - origin i), both in frame j (a column of the link Jacobian). The
    functional is carried outward once per joint and shared by every column of every later link, which costs
    fewer operations than carrying each column's wrench inward.
    """
    n = len(tf)
    Y: list[list[Scalar]] = [[0.0] * (10 * n) for _ in range(n)]
    cols = [link_wrench_columns(m) for m in motion]
    for i in range(n):
        u: Vec = [0.0, 0.0, 1.0] if tf[i].revolute else [0.0, 0.0, 0.0]
        w: Vec = [0.0, 0.0, 0.0] if tf[i].revolute else [0.0, 0.0, 1.0]
        for j in range(i, n):
            if j > i:
                # u.(R n) + u.(p x R f) + w.(R f) = (R^T u).n + (R^T (w + u x p)).f
                w = matTvec(tf[j].R, vadd(w, cross(u, tf[j].p)))
                u = matTvec(tf[j].R, u)
            for k, (f, mo) in enumerate(cols[j]):
                if wanted is None or 10 * j + k in wanted:
                    Y[i][10 * j + k] = add(dot(u, mo), dot(w, f))
    return Y


def combine(terms: list[tuple[Scalar, Scalar]]) -> Scalar:
    """``Σ pₖ eₖ`` with the terms whose ``eₖ`` are one expression up to sign taken together,
    ``(p₁ − p₂) e``: one product fewer (the moment of ``XX`` and ``ZZ`` about ``y``, ``(XX − ZZ) ωx ωz``)."""
    groups: list[tuple[Scalar, Scalar]] = []  # (expression, its coefficient)
    for coef, e in terms:
        if is_zero(coef) or is_zero(e):
            continue
        if not is_const(e) and e.is_op(ca.OP_NEG):
            coef, e = neg(coef), e.dep(0)
        for g, (ge, gc) in enumerate(groups):
            if not is_const(e) and not is_const(ge) and ca.is_equal(ge, e, 2):
                groups[g] = (ge, add(gc, coef))
                break
        else:
            groups.append((e, coef))
    return total(*(mul(c, e) for e, c in groups))


def rnea(tf: list[LinkTransform], motion: list[LinkMotion], p: list[Scalar]) -> list[Scalar]:
    """Joint forces for parameters p (10 per link, PARAMS order, about the link origins)."""
    n = len(tf)
    tau: list[Scalar] = [0.0] * n
    f: Vec = [0.0, 0.0, 0.0]
    mo: Vec = [0.0, 0.0, 0.0]
    for i in range(n - 1, -1, -1):
        cols = link_wrench_columns(motion[i])
        fi = [combine([(p[10 * i + k], cols[k][0][r]) for k in range(10)]) for r in range(3)]
        ni = [combine([(p[10 * i + k], cols[k][1][r]) for k in range(10)]) for r in range(3)]
        if i < n - 1:
            f, mo = transport(tf[i + 1], f, mo)
        f, mo = vadd(f, fi), vadd(mo, ni)
        tau[i] = mo[2] if tf[i].revolute else f[2]
    return tau
