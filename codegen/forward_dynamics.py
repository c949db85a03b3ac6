"""Forward dynamics by an unrolled LDLᵀ factorisation of the mass matrix: ``q̈ = M⁻¹ (τ − h)``.

``M = L D Lᵀ`` with ``L`` unit lower triangular, factorised from the last joint inwards
(Featherstone's LTDL order, ``M = Lᵀ D L`` with ``L`` unit lower triangular): on a chain whose
mass matrix has structural zeros (a planar or SCARA arm's decoupled joints) the factor keeps them,
because the elimination of joint ``k`` touches only the joints before it. Products with exact zeros
vanish before CasADi sees them (``algebra``), so those zeros cost nothing. One division per joint
(``1 / D_k``); everything else is multiplications and additions.
"""

from __future__ import annotations

from .algebra import Scalar, add, mul, neg, sub

Matrix = list[list[Scalar]]


def ltdl(M: Matrix) -> tuple[Matrix, list[Scalar]]:
    """``M = Lᵀ diag(d) L`` with ``L`` unit lower triangular: returns ``(L, 1/d)``.

    For ``k = n−1 … 0``: ``d_k = A_kk``, ``L_kj = A_kj / d_k`` for ``j < k``, then the Schur
    complement ``A_ij −= L_ki · A_kj`` for ``j ≤ i < k`` (``A`` the working copy of ``M``)."""
    n = len(M)
    A = [[M[i][j] for j in range(n)] for i in range(n)]
    L: Matrix = [[1.0 if i == j else 0.0 for j in range(n)] for i in range(n)]
    inv_d: list[Scalar] = [0.0] * n
    for k in range(n - 1, -1, -1):
        inv_d[k] = 1.0 / A[k][k]
        for j in range(k):
            L[k][j] = mul(A[k][j], inv_d[k])
        for i in range(k):
            for j in range(i + 1):
                A[i][j] = sub(A[i][j], mul(L[k][i], A[k][j]))
    return L, inv_d


def solve(L: Matrix, inv_d: list[Scalar], b: list[Scalar]) -> list[Scalar]:
    """``x = M⁻¹ b`` for ``M = Lᵀ D L``: ``y = L⁻ᵀ b`` (last joint first), ``z = D⁻¹ y``, ``x = L⁻¹ z``."""
    n = len(b)
    y = list(b)
    for k in range(n - 1, -1, -1):
        for j in range(k):
            y[j] = sub(y[j], mul(L[k][j], y[k]))
    x = [mul(y[k], inv_d[k]) for k in range(n)]
    for k in range(n):
        for j in range(k):
            x[k] = sub(x[k], mul(L[k][j], x[j]))
    return x


def inverse(L: Matrix, inv_d: list[Scalar]) -> Matrix:
    """``M⁻¹ = L⁻¹ D⁻¹ L⁻ᵀ`` (full symmetric): ``X = L⁻¹`` (unit lower), then
    ``(M⁻¹)_ij = Σ_{k ≤ min(i,j)} X_ik / d_k · X_jk``, the upper triangle mirrored."""
    n = len(L)
    X: Matrix = [[1.0 if i == j else 0.0 for j in range(n)] for i in range(n)]
    for i in range(n):
        for j in range(i):
            acc: Scalar = neg(L[i][j])
            for k in range(j + 1, i):
                acc = sub(acc, mul(L[i][k], X[k][j]))
            X[i][j] = acc
    S = [[mul(X[i][k], inv_d[k]) for k in range(n)] for i in range(n)]
    out: Matrix = [[0.0] * n for _ in range(n)]
    for i in range(n):
        for j in range(i + 1):
            acc = 0.0
            for k in range(j + 1):
                acc = add(acc, mul(S[i][k], X[j][k]))
            out[i][j] = out[j][i] = acc
    return out


def matmul(A: Matrix, B: Matrix) -> Matrix:
    """``A B`` with zero folding (``A`` is ``n × m``, ``B`` is ``m × p``)."""
    m, p = len(B), len(B[0])
    out: Matrix = []
    for row in A:
        out_row = []
        for j in range(p):
            acc: Scalar = 0.0
            for k in range(m):
                acc = add(acc, mul(row[k], B[k][j]))
            out_row.append(acc)
        out.append(out_row)
    return out
