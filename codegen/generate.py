"""Derive every kernel of one arm and write ``generated/<arm>.rs`` (format: ``codegen/FORMAT.md``)."""

from __future__ import annotations

import hashlib
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from . import GENERATOR_VERSION
from .algebra import Scalar
from .base_params import BaseParams, analyse, param_names, random_states
from .derivatives import inverse_dynamics_jacobians
from .dh import DhTable, load
from .emit_rust import emit
from .forward_dynamics import inverse, ltdl, matmul, solve
from .kernels import INPUT_LEN, KERNELS
from .kinematics import Symbols, transforms
from .lagrange import lagrange_function
from .newton_euler import forward, regressor, rnea


def source_hash(toml_bytes: bytes) -> str:
    return hashlib.sha256(f"dynid-codegen {GENERATOR_VERSION}\n".encode() + toml_bytes).hexdigest()


@dataclass
class Kernel:
    name: str
    args: list[str]  # Rust arguments before `out`
    inputs: list[str]  # which of trig/q/dq/ddq/theta the CasADi function takes, in order
    outputs: list[Scalar]
    out_len: str  # Rust length expression of `out`


@dataclass
class Emitted:
    name: str
    code: str
    mul: int
    add: int


def _sx(xs: list[Scalar]) -> ca.SX:
    return ca.vertcat(*[ca.SX(x) for x in xs])


def derive(arm: DhTable, base: BaseParams) -> tuple[Symbols, ca.SX, list[Kernel]]:
    n = arm.dof
    sym = Symbols.make(n)
    theta = ca.SX.sym("theta", base.rank)
    tf = transforms(arm, sym)
    g = list(arm.gravity)
    dq = [sym.dq[i] for i in range(n)]
    ddq = [sym.ddq[i] for i in range(n)]
    zero = [0.0] * n
    p_star: list[Scalar] = [0.0] * (10 * n)
    for r, col in enumerate(base.kept):
        p_star[col] = theta[r]

    full = forward(tf, dq, ddq, g)
    Y = regressor(tf, full)
    Yb_rows = regressor(tf, full, set(base.kept))
    Yb = [[row[c] for c in base.kept] for row in Yb_rows]

    M: list[list[Scalar]] = [[0.0] * n for _ in range(n)]
    for k in range(n):
        e_k: list[Scalar] = [1.0 if i == k else 0.0 for i in range(n)]
        col = rnea(tf, forward(tf, zero, e_k, [0.0, 0.0, 0.0]), p_star)
        for i in range(k, n):
            M[i][k] = M[k][i] = col[i]

    h = rnea(tf, forward(tf, dq, zero, g), p_star)
    tau = rnea(tf, full, p_star)
    L, inv_d = ltdl(M)
    qdd = solve(L, inv_d, [sym.tau[i] - h[i] for i in range(n)])
    M_inv = inverse(L, inv_d)
    J_q, J_dq = inverse_dynamics_jacobians(sym, tau)
    # ∂q̈/∂x = −M⁻¹ ∂τ/∂x at q̈ = FD(q, q̇, τ): the same Jacobians with q̈ replaced by its expression.
    J_fd = ca.substitute([J_q, J_dq], [sym.ddq], [ca.vertcat(*[ca.SX(x) for x in qdd])])
    dqdd = [matmul(M_inv, [[-J[r, c] for c in range(n)] for r in range(n)]) for J in J_fd]

    def flat(*mats) -> list[Scalar]:
        return [m[r][c] if isinstance(m, list) else m[r, c] for m in mats for r in range(n) for c in range(n)]

    outputs: dict[str, list[Scalar]] = {
        "regressor": [y for row in Y for y in row],
        "base_regressor": [y for row in Yb for y in row],
        "mass_matrix": flat(M),
        "bias": h,
        "gravity": rnea(tf, forward(tf, zero, zero, g), p_star),
        "inverse_dynamics": tau,
        "forward_dynamics": qdd,
        "inverse_mass_matrix": flat(M_inv),
        "inverse_dynamics_derivatives": flat(J_q, J_dq),
        "forward_dynamics_derivatives": flat(dqdd[0], dqdd[1], M_inv),
    }
    if set(outputs) != {k.name for k in KERNELS}:
        raise AssertionError(f"derive() and codegen/kernels.py disagree: {sorted(outputs)}")
    kernels = [
        Kernel(
            k.name,
            [f"{v}: &[f64; {INPUT_LEN[v]}]" for v in k.inputs],
            ["trig", *k.inputs],
            outputs[k.name],
            k.out_len,
        )
        for k in KERNELS
    ]
    return sym, theta, kernels


def check_against_lagrange(arm: DhTable, sym: Symbols, Y: list[Scalar], samples: int = 4) -> float:
    """Max |Y_NE - Y_Lagrange| / max|Y| over random states; raises if they disagree."""
    f_ne = ca.Function("ne", [sym.trig, sym.q, sym.dq, sym.ddq], [_sx(Y)])
    f_lg = lagrange_function(arm)
    q, dq, ddq = random_states(arm, samples, np.random.default_rng(7))
    worst = 0.0
    for s in range(samples):
        ang = q[s] + [j.theta for j in arm.joints]
        trig = np.empty(2 * arm.dof)
        trig[0::2], trig[1::2] = np.cos(ang), np.sin(ang)
        a = np.array(f_ne(trig, q[s], dq[s], ddq[s])).ravel()
        b = np.array(f_lg(q[s], dq[s], ddq[s])).reshape(-1)
        b = np.array(f_lg(q[s], dq[s], ddq[s])).reshape(arm.dof, 10 * arm.dof).ravel()
        worst = max(worst, float(np.max(np.abs(a - b)) / (1.0 + np.max(np.abs(b)))))
    if worst > 1e-9:
        raise ArithmeticError(f"{arm.name}: Newton-Euler and Lagrange regressors differ by {worst:.3e}")
    return worst


def emit_kernel(arm: DhTable, sym: Symbols, theta: ca.SX, k: Kernel) -> Emitted:
    vectors = {"trig": sym.trig, "q": sym.q, "dq": sym.dq, "ddq": sym.ddq, "tau": sym.tau, "theta": theta}
    out = ca.cse(_sx(k.outputs))
    f = ca.Function(k.name, [vectors[v] for v in k.inputs], [out])

    def name(inp: int, nz: int) -> str:
        which = k.inputs[inp]
        if which == "trig":
            return f"{'c' if nz % 2 == 0 else 's'}{nz // 2 + 1}"
        return f"{which}[{nz}]"

    body = emit(f, name, len(k.outputs))
    trig_joints = sorted({nz // 2 for inp, nz in body.used if k.inputs[inp] == "trig"})

    def arg(i: int) -> str:
        off = arm.joints[i].theta
        return f"q[{i}]" if off == 0.0 else f"q[{i}] + {off!r}"

    # Four joints per `sin_cos4` (one evaluation of the four-lane polynomial, the same values as
    # one `sin_cos` call per joint); a kernel of two or three joints in all through `sin_cos2` or
    # `sin_cos3` (planar2 and SCARA kernels 1.1-1.2x faster), but the joints left after a group
    # of four one by one (a `sin_cos2` there made the Panda gravity 1.16x slower, in 5 rounds).
    pre = []
    groups = [trig_joints[g : g + 4] for g in range(0, len(trig_joints), 4)]
    if len(groups) > 1 and len(groups[-1]) < 4:
        groups = groups[:-1] + [[i] for i in groups[-1]]
    for js in groups:
        if len(js) == 1:
            pre.append(f"let (s{js[0] + 1}, c{js[0] + 1}) = crate::trig::sin_cos({arg(js[0])});")
            continue
        pairs = ", ".join(f"(s{i + 1}, c{i + 1})" for i in js)
        args = ", ".join(arg(i) for i in js)
        pre.append(f"let [{pairs}] = crate::trig::sin_cos{len(js)}({args});")
    sig = ", ".join(k.args + [f"out: &mut [f64; {k.out_len}]"])
    lines = [f"#[inline]\npub fn {k.name}({sig}) {{"]
    lines += [f"    {ln}" for ln in pre + body.lines]
    lines.append("}")
    return Emitted(k.name, "\n".join(lines), body.mul, body.add)


def _str_array(xs: list[str]) -> str:
    return "[" + ", ".join(f'"{x}"' for x in xs) + "]"


def render(arm: DhTable, toml_name: str, digest: str, base: BaseParams, kernels: list[Emitted]) -> str:
    n = arm.dof
    head = [
        f"// @generated by dynid-codegen {GENERATOR_VERSION} from arms/{toml_name} — DO NOT EDIT.",
        f"// source-hash: {digest}",
        f"// regenerate: cargo build (build.rs) or python -m codegen {arm.name}",
        "//",
        "// Operation counts (multiplications / additions):",
    ]
    head += [f"//   {e.name:<17} {e.mul:>6} / {e.add:<6}" for e in kernels]
    head += ["//", "// Base parameters (theta = B p):"]
    head += [f"//   {nm} = {ex}" for nm, ex in zip(base.names, base.exprs)]
    body = [
        "",
        f'pub const NAME: &str = "{arm.name}";',
        f"pub const DOF: usize = {n};",
        f"pub const NP: usize = {10 * n};",
        f"pub const NB: usize = {base.rank};",
        f'pub const GENERATOR_VERSION: &str = "{GENERATOR_VERSION}";',
        f'pub const SOURCE_HASH: &str = "{digest}";',
        f"pub const PARAM_NAMES: [&str; NP] = {_str_array(param_names(n))};",
        f"pub const BASE_PARAM_NAMES: [&str; NB] = {_str_array(base.names)};",
        f"pub const BASE_PARAM_EXPRS: [&str; NB] = {_str_array(base.exprs)};",
        "/// Sparse base-parameter map: `theta[row] += coef * p[col]`.",
        f"pub const BASE_MAP: [(usize, usize, f64); {len(base.entries)}] = ["
        + ", ".join(f"({r}, {c}, {float(v)!r})" for r, c, v in base.entries)
        + "];",
        "/// `(kernel, multiplications, additions)` as counted by the generator.",
        f"pub const OP_COUNTS: [(&str, u32, u32); {len(kernels)}] = ["
        + ", ".join(f'("{e.name}", {e.mul}, {e.add})' for e in kernels)
        + "];",
        "",
    ]
    for e in kernels:
        body += [e.code, ""]
    bp = ["#[inline]", "pub fn base_params(p: &[f64; NP], out: &mut [f64; NB]) {"]
    rows: dict[int, list[str]] = {}
    for r, c, v in base.entries:
        rows.setdefault(r, []).append(f"p[{c}]" if v == 1.0 else f"{v!r} * p[{c}]")
    for r in range(base.rank):
        bp.append(f"    out[{r}] = {' + '.join(rows[r])};")
    bp.append("}")
    return "\n".join(head + body + bp) + "\n"


def write_atomic(path: Path, text: str) -> bool:
    """Write only if the content changed; temp file + rename. Returns whether it wrote."""
    if path.exists() and path.read_text(encoding="utf-8") == text:
        return False
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return True


@dataclass
class Result:
    arm: str
    text: str
    seconds: float
    ops: list[tuple[str, int, int]]
    nb: int
    lagrange_error: float


def generate(toml_path: Path) -> Result:
    t0 = time.perf_counter()
    arm = load(toml_path)
    if arm.name != toml_path.stem:
        raise ValueError(f'{toml_path}: name = "{arm.name}" must equal the file stem "{toml_path.stem}"')
    digest = source_hash(toml_path.read_bytes())
    base = analyse(arm)
    sym, theta, kernels = derive(arm, base)
    lag = check_against_lagrange(arm, sym, kernels[0].outputs)
    emitted = [emit_kernel(arm, sym, theta, k) for k in kernels]
    text = render(arm, toml_path.name, digest, base, emitted)
    ops = [(e.name, e.mul, e.add) for e in emitted]
    return Result(arm.name, text, time.perf_counter() - t0, ops, base.rank, lag)
