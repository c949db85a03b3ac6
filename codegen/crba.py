"""The mass matrix by the composite-rigid-body algorithm, on the parameters the kernel is given.

``M`` is linear in the link parameters, so the composite inertia of links ``i…n`` can be formed from
the parameters first (each child's 10 parameters moved into its parent's frame and added), and each
column then read off one composite body's momentum carried inward: ``M[i][j] = Sᵢᵀ Xᵀ Icⱼ Sⱼ``.
That costs fewer operations than one Newton–Euler pass per column with a unit acceleration, which
redoes the whole chain each time; the values are the same up to rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

from .algebra import Scalar, Vec, add, dot, matvec, mul, neg, sub, vadd
from .kinematics import LinkTransform
from .newton_euler import transport


@dataclass
class Body:
    """Inertia about the frame origin (``xx, xy, xz, yy, yz, zz``), first moment ``h``, mass ``m``."""

    inertia: list[Scalar]
    h: Vec
    m: Scalar


def _rotate_z(b: Body, c: Scalar, s: Scalar) -> Body:
    """``Rz b Rzᵀ`` by the joint angle; the ``xx, xy, yy`` block through the double angle
    (``sin 2q = 2cs``, ``cos 2q = 1 − 2s²``): four products instead of nine."""
    xx, xy, xz, yy, yz, zz = b.inertia
    ss, cs = mul(s, s), mul(c, s)
    sin2, cos2 = mul(2.0, cs), sub(1.0, mul(2.0, ss))
    d = sub(xx, yy)
    a = add(mul(d, ss), mul(xy, sin2))
    return Body(
        [
            sub(xx, a),
            add(mul(d, cs), mul(xy, cos2)),
            sub(mul(c, xz), mul(s, yz)),
            add(yy, a),
            add(mul(s, xz), mul(c, yz)),
            zz,
        ],
        [sub(mul(c, b.h[0]), mul(s, b.h[1])), add(mul(s, b.h[0]), mul(c, b.h[1])), b.h[2]],
        b.m,
    )


def _rotate(R: list[list[Scalar]], b: Body) -> Body:
    """``R b Rᵀ`` for any rotation; a constant D-H twist of 0 or ±90° is a signed permutation (free)."""
    xx, xy, xz, yy, yz, zz = b.inertia
    inertia = [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]
    ri = [matvec(inertia, R[r]) for r in range(3)]  # rows of R I (I symmetric)
    full = [[dot(ri[r], R[k]) for k in range(3)] for r in range(3)]
    return Body([full[0][0], full[0][1], full[0][2], full[1][1], full[1][2], full[2][2]], matvec(R, b.h), b.m)


def _to_parent(t: LinkTransform, cs: tuple[Scalar, Scalar] | None, b: Body) -> Body:
    """Body ``b`` of frame i in frame i−1, about origin i−1 (``t``: frame i in frame i−1; ``cs``:
    the revolute joint's cosine and sine, ``t.R = RotX(α) RotZ(q)``)."""
    if cs is not None:
        ca_, sa = t.R[2][2], neg(t.R[1][2])
        b = _rotate([[1.0, 0.0, 0.0], [0.0, ca_, neg(sa)], [0.0, sa, ca_]], _rotate_z(b, *cs))
    else:
        b = _rotate(t.R, b)
    p, h, m = t.p, b.h, b.m
    ph, pp = dot(p, h), dot(p, p)
    xx, xy, xz, yy, yz, zz = b.inertia

    def diag(k: int, v: Scalar) -> Scalar:  # + m(|p|² − p_k²) + 2(p·h − p_k h_k)
        return add(v, add(mul(m, sub(pp, mul(p[k], p[k]))), mul(2.0, sub(ph, mul(p[k], h[k])))))

    def off(a: int, k: int, v: Scalar) -> Scalar:  # − m p_a p_k − (p_a h_k + h_a p_k)
        return sub(v, add(mul(m, mul(p[a], p[k])), add(mul(p[a], h[k]), mul(h[a], p[k]))))

    inertia = [diag(0, xx), off(0, 1, xy), off(0, 2, xz), diag(1, yy), off(1, 2, yz), diag(2, zz)]
    return Body(inertia, vadd(h, [mul(m, x) for x in p]), m)


def mass_matrix(tf: list[LinkTransform], trig, p: list[Scalar]) -> list[list[Scalar]]:
    """``M(q)`` for parameters ``p`` (10 per link, ``newton_euler.PARAMS`` order); ``trig`` holds
    ``c1, s1, c2, …``. Composite bodies inward, then per column ``j`` the spatial force ``Icⱼ Sⱼ``
    carried to each joint ``i < j`` (``newton_euler.transport``), whose axis picks ``M[i][j]``."""
    n = len(tf)
    comp: list[Body] = [Body([], [], 0.0)] * n
    for i in range(n - 1, -1, -1):
        pi = p[10 * i : 10 * i + 10]
        own = Body(list(pi[:6]), list(pi[6:9]), pi[9])
        if i < n - 1:
            cs = (trig[2 * i + 2], trig[2 * i + 3]) if tf[i + 1].revolute else None
            child = _to_parent(tf[i + 1], cs, comp[i + 1])
            own = Body(
                [add(a, b) for a, b in zip(own.inertia, child.inertia)], vadd(own.h, child.h), add(own.m, child.m)
            )
        comp[i] = own
    M: list[list[Scalar]] = [[0.0] * n for _ in range(n)]
    for j in range(n):
        b = comp[j]
        if tf[j].revolute:  # unit rotation about z: f = z × h, n = I z
            f, mo = [neg(b.h[1]), b.h[0], 0.0], [b.inertia[2], b.inertia[4], b.inertia[5]]
        else:  # unit translation along z: f = m z, n = h × z
            f, mo = [0.0, 0.0, b.m], [b.h[1], neg(b.h[0]), 0.0]
        M[j][j] = mo[2] if tf[j].revolute else f[2]
        for i in range(j - 1, -1, -1):
            f, mo = transport(tf[i + 1], f, mo)
            M[i][j] = M[j][i] = mo[2] if tf[i].revolute else f[2]
    return M
