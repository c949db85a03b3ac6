"""Link transforms of a modified (Craig) D-H table with symbolic joint variables.

Frame i from frame i-1: RotX(alpha_{i-1}) TransX(a_{i-1}) RotZ(theta_i) TransZ(d_i). A revolute joint's angle
enters only through its cosine and sine, which are kernel inputs (computed once per call with sin_cos), so
the derived expressions are polynomials.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from .algebra import Scalar, mul, neg
from .dh import DhTable, cos_sin


@dataclass
class Symbols:
    """Kernel inputs as CasADi symbols, one vector per Rust argument."""

    dof: int
    trig: ca.SX  # [c1, s1, c2, s2, ...] (entries of prismatic joints unused)
    q: ca.SX  # joint variables (used only for prismatic joints)
    dq: ca.SX
    ddq: ca.SX
    tau: ca.SX  # joint forces (the forward-dynamics kernels' input)

    @staticmethod
    def make(dof: int) -> Symbols:
        return Symbols(
            dof,
            ca.SX.sym("trig", 2 * dof),
            ca.SX.sym("q", dof),
            ca.SX.sym("dq", dof),
            ca.SX.sym("ddq", dof),
            ca.SX.sym("tau", dof),
        )


@dataclass
class LinkTransform:
    """Rotation R (frame i in frame i-1) and origin p of frame i in frame i-1."""

    R: list[list[Scalar]]
    p: list[Scalar]
    revolute: bool


def transforms(arm: DhTable, sym: Symbols, lengths: dict[str, Scalar] | None = None) -> list[LinkTransform]:
    """One transform per joint. ``lengths`` may replace the numeric a/d constants by symbols."""
    out = []
    for i, j in enumerate(arm.joints):
        ca_, sa = cos_sin(j.alpha)
        a: Scalar = j.a
        d: Scalar = j.d
        if lengths is not None:
            a = lengths.get(f"a{i}", a)
            d = lengths.get(f"d{i + 1}", d)
        if j.kind == "revolute":
            c, s = sym.trig[2 * i], sym.trig[2 * i + 1]
        else:
            c, s = cos_sin(j.theta)
            d = sym.q[i] + d if d != 0.0 else sym.q[i]
        R = [
            [c, neg(s), 0.0],
            [mul(ca_, s), mul(ca_, c), -sa],
            [mul(sa, s), mul(sa, c), ca_],
        ]
        p = [a, mul(-sa, d), mul(ca_, d)]
        out.append(LinkTransform(R, p, j.kind == "revolute"))
    return out


def length_symbols(arm: DhTable) -> dict[str, float]:
    """Nonzero constant lengths by Craig's names: row i holds a_{i-1} and d_i (prismatic d_i excluded)."""
    out = {}
    for i, j in enumerate(arm.joints):
        if j.a != 0.0:
            out[f"a{i}"] = j.a
        if j.d != 0.0 and j.kind == "revolute":
            out[f"d{i + 1}"] = j.d
    return out
