"""Scalar and 3-vector helpers over Python floats and CasADi SX scalars.

Constants stay Python floats so that products with exact zeros and ones vanish before CasADi sees them:
this zero propagation is what turns +-90 degree D-H rotations into signed permutations.
"""

from __future__ import annotations

import casadi as ca

Scalar = float | ca.SX
Vec = list  # three Scalars


def is_const(x: Scalar) -> bool:
    return isinstance(x, float) or bool(x.is_constant())


def value(x: Scalar) -> float:
    return x if isinstance(x, float) else float(x)


def is_zero(x: Scalar) -> bool:
    return is_const(x) and value(x) == 0.0


def add(x: Scalar, y: Scalar) -> Scalar:
    if is_zero(x):
        return y
    if is_zero(y):
        return x
    if is_const(x) and is_const(y):
        return value(x) + value(y)
    return x + y


def sub(x: Scalar, y: Scalar) -> Scalar:
    return add(x, neg(y))


def neg(x: Scalar) -> Scalar:
    return -value(x) if is_const(x) else -x


def mul(x: Scalar, y: Scalar) -> Scalar:
    if is_zero(x) or is_zero(y):
        return 0.0
    if is_const(x) and is_const(y):
        return value(x) * value(y)
    if is_const(x):
        x, y = y, x
    if is_const(y):
        c = value(y)
        if c == 1.0:
            return x
        if c == -1.0:
            return -x
    return x * y


def total(*xs: Scalar) -> Scalar:
    acc: Scalar = 0.0
    for x in xs:
        acc = add(acc, x)
    return acc


def vadd(u: Vec, v: Vec) -> Vec:
    return [add(a, b) for a, b in zip(u, v)]


def vsub(u: Vec, v: Vec) -> Vec:
    return [sub(a, b) for a, b in zip(u, v)]


def vscale(k: Scalar, u: Vec) -> Vec:
    return [mul(k, a) for a in u]


def cross(u: Vec, v: Vec) -> Vec:
    return [
        sub(mul(u[1], v[2]), mul(u[2], v[1])),
        sub(mul(u[2], v[0]), mul(u[0], v[2])),
        sub(mul(u[0], v[1]), mul(u[1], v[0])),
    ]


def dot(u: Vec, v: Vec) -> Scalar:
    return total(*(mul(a, b) for a, b in zip(u, v)))


def matvec(m: list[list[Scalar]], v: Vec) -> Vec:
    return [dot(row, v) for row in m]


def matTvec(m: list[list[Scalar]], v: Vec) -> Vec:
    return [dot([m[0][j], m[1][j], m[2][j]], v) for j in range(3)]


def matmul(a: list[list[Scalar]], b: list[list[Scalar]]) -> list[list[Scalar]]:
    return [[dot(a[i], [b[0][j], b[1][j], b[2][j]]) for j in range(3)] for i in range(3)]
