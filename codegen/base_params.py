"""Base (identifiable) parameters: numeric column selection, symbolic regrouping.

1. The full regressor is evaluated on random states; columns are taken greedily in link order 1..n and, within
   a link, in PARAMS order (XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M); a column is kept when it is not in the span
   of those already kept. The kept columns form the base regressor, so Y p = Yb theta with
   theta = p_kept + K p_dropped.
2. Each entry of K is a homogeneous polynomial in the arm's constant lengths (its degree is the difference of
   the two parameters' length dimensions). It is recovered exactly by evaluating K for random lengths and
   fitting small rational coefficients; if that fails (e.g. a general twist angle) the number is kept.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from fractions import Fraction

import casadi as ca
import numpy as np

from .dh import DhTable
from .kinematics import Symbols, length_symbols, transforms
from .newton_euler import PARAMS, forward, regressor

DIM = {"XX": 2, "XY": 2, "XZ": 2, "YY": 2, "YZ": 2, "ZZ": 2, "MX": 1, "MY": 1, "MZ": 1, "M": 0}
SEED = 20221106
N_STATES = 48


def param_names(n: int) -> list[str]:
    return [f"{p}{j + 1}" for j in range(n) for p in PARAMS]


@dataclass
class Polynomial:
    """sum(coef * prod(lengths[name] ** power)) with rational coefficients."""

    terms: list[tuple[Fraction, tuple[tuple[str, int], ...]]]

    def value(self, lengths: dict[str, float]) -> float:
        acc = 0.0
        for coef, mono in self.terms:
            term = float(coef)
            for name, power in mono:
                term *= lengths[name] ** power
            acc += term
        return acc


@dataclass
class BaseParams:
    names: list[str]  # base-parameter names, e.g. ZZR1
    kept: list[int]  # full-parameter index of each base column
    exprs: list[str]  # human-readable grouping, e.g. "ZZ1 + a1²·M2"
    entries: list[tuple[int, int, float]]  # theta[row] += coef * p[col]
    rank: int
    symbolic: bool  # every coefficient recovered exactly


def _regressor_function(arm: DhTable) -> tuple[ca.Function, list[str]]:
    names = sorted(length_symbols(arm))
    L = ca.SX.sym("L", len(names))
    sym = Symbols.make(arm.dof)
    tf = transforms(arm, sym, {nm: L[k] for k, nm in enumerate(names)})
    motion = forward(tf, [sym.dq[i] for i in range(arm.dof)], [sym.ddq[i] for i in range(arm.dof)], list(arm.gravity))
    Y = regressor(tf, motion)
    flat = ca.vertcat(*[ca.SX(y) for row in Y for y in row])
    return ca.Function("Y", [sym.trig, sym.q, sym.dq, sym.ddq, L], [flat]), names


def random_states(arm: DhTable, count: int, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    n = arm.dof
    q = rng.uniform(-np.pi, np.pi, (count, n))
    for i, j in enumerate(arm.joints):
        if j.kind == "prismatic":
            q[:, i] = rng.uniform(-0.5, 0.5, count)
    dq = rng.uniform(-2, 2, (count, n))
    ddq = rng.uniform(-5, 5, (count, n))
    return q, dq, ddq


def _stacked(f: ca.Function, arm: DhTable, states, lengths: np.ndarray) -> np.ndarray:
    q, dq, ddq = states
    n, count = arm.dof, q.shape[0]
    trig = np.empty((count, 2 * n))
    trig[:, 0::2] = np.cos(q + [j.theta for j in arm.joints])
    trig[:, 1::2] = np.sin(q + [j.theta for j in arm.joints])
    fm = f.map(count)
    out = np.array(fm(trig.T, q.T, dq.T, ddq.T, np.tile(lengths.reshape(-1, 1), (1, count))))
    # out: (n*NP) x count, row-major per sample -> (count*n) x NP
    return out.T.reshape(count * n, 10 * n)


def _select(A: np.ndarray) -> tuple[list[int], list[int]]:
    norms = np.linalg.norm(A, axis=0)
    scale = norms.max()
    kept: list[int] = []
    Q = np.zeros((A.shape[0], 0))
    dropped = []
    for col in range(A.shape[1]):
        v = A[:, col]
        if norms[col] <= 1e-11 * scale:
            continue
        r = v - Q @ (Q.T @ v)
        r = r - Q @ (Q.T @ r)
        if np.linalg.norm(r) > 1e-7 * norms[col]:
            kept.append(col)
            Q = np.hstack([Q, (r / np.linalg.norm(r)).reshape(-1, 1)])
        else:
            dropped.append(col)
    return kept, dropped


def _grouping(A: np.ndarray, kept: list[int], dropped: list[int]) -> np.ndarray:
    K, *_ = np.linalg.lstsq(A[:, kept], A[:, dropped], rcond=None)
    resid = np.linalg.norm(A[:, kept] @ K - A[:, dropped]) / max(1.0, np.linalg.norm(A[:, dropped]))
    if resid > 1e-8:
        raise ArithmeticError(f"base-parameter regrouping does not reproduce the regressor (residual {resid:.2e})")
    return K


def _monomials(names: list[str], degree: int) -> list[tuple[tuple[str, int], ...]]:
    out = []
    for combo in itertools.combinations_with_replacement(names, degree):
        out.append(tuple((nm, combo.count(nm)) for nm in sorted(set(combo))))
    return out


def _fit(samples: list[dict[str, float]], values: np.ndarray, names: list[str], degree: int) -> Polynomial | None:
    if degree < 0:
        return None
    monos = _monomials(names, degree)
    Phi = np.array([[np.prod([s[nm] ** pw for nm, pw in mono]) for mono in monos] for s in samples])
    coef, *_ = np.linalg.lstsq(Phi, values, rcond=None)
    if np.max(np.abs(Phi @ coef - values)) > 1e-8 * (1.0 + np.max(np.abs(values))):
        return None
    terms = []
    for c, mono in zip(coef, monos):
        r = Fraction(float(c)).limit_denominator(12)
        if abs(float(r) - c) > 1e-7:
            return None
        if r != 0:
            terms.append((r, mono))
    return Polynomial(terms)


def _superscript(power: int) -> str:
    return "" if power == 1 else str(power).translate(str.maketrans("0123456789", "⁰¹²³⁴⁵⁶⁷⁸⁹"))


def _format_poly(poly: Polynomial) -> tuple[str, str]:
    """(sign, magnitude text without the parameter), e.g. ('+', 'a1²')."""
    parts = []
    for coef, mono in poly.terms:
        factors = [f"{nm}{_superscript(pw)}" for nm, pw in mono]
        mag = abs(coef)
        if mag != 1 or not factors:
            factors.insert(0, str(mag))
        parts.append(("-" if coef < 0 else "+", "·".join(factors)))
    if len(parts) == 1:
        return parts[0]
    if all(s == "-" for s, _ in parts):
        return "-", "(" + " + ".join(t for _, t in parts) + ")"
    parts.sort(key=lambda st: st[0] == "-")  # stable: positive terms first, e.g. (d5² − a4²)
    body = parts[0][1]
    for s, t in parts[1:]:
        body += f" {'+' if s == '+' else '−'} {t}"
    return "+", f"({body})"


def _format_number(c: float) -> tuple[str, str]:
    return ("-" if c < 0 else "+", f"{abs(c):.6g}")


def analyse(arm: DhTable) -> BaseParams:
    n = arm.dof
    pnames = param_names(n)
    f, lnames = _regressor_function(arm)
    nominal = {nm: v for nm, v in length_symbols(arm).items()}
    L0 = np.array([nominal[nm] for nm in lnames])
    rng = np.random.default_rng(SEED)
    states = random_states(arm, max(N_STATES, 4 * 10 * n // n), rng)
    A = _stacked(f, arm, states, L0)
    kept, dropped = _select(A)
    K = _grouping(A, kept, dropped)

    # Exact coefficients: refit K over random lengths (same states, same column choice).
    n_fit = len(_monomials(lnames, 2)) + 12 if lnames else 1
    samples, Ks = [], []
    for _ in range(n_fit):
        Ls = np.array([np.sign(v) * rng.uniform(0.3, 1.3) for v in L0])
        samples.append(dict(zip(lnames, Ls)))
        Ks.append(_grouping(_stacked(f, arm, states, Ls), kept, dropped))
    Ks_arr = np.array(Ks)

    entries: list[tuple[int, int, float]] = []
    names, exprs = [], []
    symbolic = True
    for row, col in enumerate(kept):
        entries.append((row, col, 1.0))
        text = pnames[col]
        grouped = False
        for k, dcol in enumerate(dropped):
            nominal_c = K[row, k]
            values = Ks_arr[:, row, k]
            if abs(nominal_c) < 1e-10 and np.max(np.abs(values)) < 1e-10:
                continue
            degree = DIM[PARAMS[col % 10]] - DIM[PARAMS[dcol % 10]]
            poly = _fit(samples, values, lnames, degree) if lnames else None
            if poly is None and not lnames and abs(nominal_c - round(nominal_c)) < 1e-9:
                poly = Polynomial([(Fraction(round(nominal_c)), ())])
            if poly is not None and abs(poly.value(nominal) - nominal_c) < 1e-8 * (1 + abs(nominal_c)):
                coef = poly.value(nominal)
                sign, mag = _format_poly(poly)
            else:
                symbolic = False
                coef = float(f"{nominal_c:.12g}")
                sign, mag = _format_number(coef)
            if coef == 0.0:
                continue
            grouped = True
            entries.append((row, dcol, coef))
            text += f" {'+' if sign == '+' else '−'} " + (f"{mag}·{pnames[dcol]}" if mag != "1" else pnames[dcol])
        p, link = PARAMS[col % 10], col // 10 + 1
        names.append(f"{p}R{link}" if grouped else f"{p}{link}")
        exprs.append(text)
    return BaseParams(names, kept, exprs, entries, len(kept), symbolic)
