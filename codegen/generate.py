"""Derive every kernel of one arm and write ``generated/<arm>.rs`` (format: ``codegen/FORMAT.md``)."""

from __future__ import annotations

import hashlib
import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from . import GENERATOR_VERSION
from .algebra import Scalar
from .base_params import BaseParams, analyse, param_names, random_states
from .crba import mass_matrix
from .derivatives import inverse_dynamics_jacobians, inverse_dynamics_jvp
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
    parts: list[Part] = field(default_factory=list)  # helpers of a compact scalar form (FORMAT.md)


@dataclass
class Part:
    """A straight-line helper of a kernel's compact scalar form: `fn <kernel>_part_<name>`, its
    arguments `(name, Rust length, CasADi vector)` before `out` (the joints' cosines and sines
    passed in as `t`, not computed), and its outputs."""

    name: str
    args: list[tuple[str, str, ca.SX]]
    outputs: list[Scalar]
    out_len: str


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

    M = mass_matrix(tf, sym.trig, p_star)

    h = rnea(tf, forward(tf, dq, zero, g), p_star)
    tau = rnea(tf, full, p_star)
    L, inv_d = ltdl(M)
    qdd = solve(L, inv_d, [sym.tau[i] - h[i] for i in range(n)])
    M_inv = inverse(L, inv_d)
    J_q, J_dq = inverse_dynamics_jacobians(sym, tau)
    # ∂q̈/∂x = −M⁻¹ ∂τ/∂x at q̈ = FD(q, q̇, τ): the same Jacobians with q̈ replaced by its expression.
    J_fd = ca.substitute([J_q, J_dq], [sym.ddq], [ca.vertcat(*[ca.SX(x) for x in qdd])])
    dqdd = [matmul(M_inv, [[-J[r, c] for c in range(n)] for r in range(n)]) for J in J_fd]
    # The compact scalar form of the same (see `_compact_fdd`): q̈ and M⁻¹ in one straight-line
    # part, the columns of ∂τ/∂x from a directional-derivative part evaluated eight directions
    # at a time.
    d, jvp = inverse_dynamics_jvp(sym, tau)
    t = ("t", "2 * DOF", sym.trig)
    fdd_parts = [
        Part(
            "fdm",
            [t, ("q", "DOF", sym.q), ("dq", "DOF", sym.dq), ("tau", "DOF", sym.tau), ("theta", "NB", theta)],
            [*qdd, *[M_inv[r][c] for r in range(n) for c in range(n)]],
            "DOF + DOF * DOF",
        ),
        Part(
            "jvp",
            [t, ("q", "DOF", sym.q), ("dq", "DOF", sym.dq), ("ddq", "DOF", sym.ddq), ("theta", "NB", theta)]
            + [("d", "2 * DOF", d)],
            [jvp[i] for i in range(n)],
            "DOF",
        ),
    ]

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
            fdd_parts if k.name == "forward_dynamics_derivatives" else [],
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


# A straight-line kernel of this many operations or more takes its sines and cosines four at a
# time, not from one `sin_cos8`: the Panda inverse dynamics derivatives (5749 operations) was
# 1.04x [1.01-1.04] faster so (3 interleaved rounds), the PUMA 560 one (3304) 1.85x slower.
EIGHT_MAX_OPS = 5000


def _trig_prelude(arm: DhTable, trig_joints: list[int], eight: bool = True) -> list[str]:
    """`let (s<i>, c<i>) = ...` for the joints whose cosine or sine a kernel reads."""

    def arg(i: int) -> str:
        off = arm.joints[i].theta
        return f"q[{i}]" if off == 0.0 else f"q[{i}] + {off!r}"

    # Four joints per `sin_cos4` (one evaluation of the four-lane polynomial, the same values as
    # one `sin_cos` call per joint); a kernel of two or three joints in all through `sin_cos2` or
    # `sin_cos3` (planar2 and SCARA kernels 1.1-1.2x faster), but the joints left after a group
    # of four one by one (a `sin_cos2` there made the Panda gravity 1.16x slower, in 5 rounds).
    # Five to eight joints: one `sin_cos8` (one eight-lane evaluation where the crate has
    # AVX-512F, a quarter of the instructions of a `sin_cos4` and one `sin_cos` per joint left).
    # Not in kernels of EIGHT_MAX_OPS operations or more (see there).
    if eight and 5 <= len(trig_joints) <= 8:
        pairs = ", ".join(f"(s{i + 1}, c{i + 1})" for i in trig_joints)
        args = ", ".join(arg(i) for i in trig_joints)
        return [f"let [{pairs}] = crate::trig::sin_cos8([{args}]);"]
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
    return pre


def _emit_part(kernel: str, part: Part) -> tuple[str, Emitted]:
    """`fn <kernel>_part_<name>`: straight-line, as the kernels, with `t` an argument."""
    f = ca.Function(part.name, [v for _, _, v in part.args], [ca.cse(_sx(part.outputs))])
    body = emit(f, lambda i, nz: f"{part.args[i][0]}[{nz}]", len(part.outputs))
    sig = ", ".join([f"{a}: &[f64; {ln}]" for a, ln, _ in part.args] + [f"out: &mut [f64; {part.out_len}]"])
    name = f"{kernel}_part_{part.name}"
    lines = [f"#[inline]\npub fn {name}({sig}) {{", *[f"    {ln}" for ln in body.lines], "}"]
    trig = sorted({nz // 2 for inp, nz in body.used if part.args[inp][0] == "t"})
    return ",".join(map(str, trig)), Emitted(name, "\n".join(lines), body.mul, body.add)


# Directions per call of the directional-derivative part: one per lane of a four-lane AVX pack.
# Measured on this machine (AMD EPYC, Zen 4, whose AVX-512 issues each 512-bit operation as two
# 256-bit halves), Panda, same binary: ∂ID 523-559 ns with four lanes against 654-655 with eight
# (AVX-512) and 805 fused; ∂FD 859-916 against 925-934 and 1155.
LANES = 4
# A kernel gets its compact scalar form from this many operations of the fused one (about 8.5
# bytes of machine code each, against a 32 KiB L1i). Measured with four-lane calls (0.3.8): PUMA 560
# ∂FD (4806) 416-446 ns against 692-696 fused; its ∂ID (3179) from the same part 285-297 against
# 279, so a ∂ID under this many operations keeps its fused kernel too; the Panda (7719 and 5314)
# as in docs/derivatives.md. (With eight-lane calls, 0.3.0, PUMA's ∂FD was slower.)
COMPACT_MIN_OPS = 4000
# The compact forms' lane part runs as AVX code where the crate is built with AVX and FMA on
# x86-64 (elsewhere a pack is four scalars, which LLVM does not vectorise: the fused kernel then).
_AVX = 'all(target_arch = "x86_64", target_feature = "avx", target_feature = "fma")'
_AVX_CFG = f"#[cfg({_AVX})]"
_NO_AVX_CFG = f"#[cfg(not({_AVX}))]"


def _calls(n: int) -> int:
    """Four-lane calls that cover the `2n` unit directions of `(q, q̇)`."""
    return -(-2 * n // LANES)


def _dispatch(doc: str, name: str, sig: str, args: str) -> str:
    """The public kernel of a compact form: `<name>_wide` where the crate is built with AVX and
    FMA, else `<name>_fused` (the straight-line kernel)."""
    return f"""{doc}
#[inline]
pub fn {name}({sig}) {{
    {_AVX_CFG}
    {name}_wide({args});
    {_NO_AVX_CFG}
    {name}_fused({args});
}}
"""


def _columns(jvp: str, calls: int, store: list[str]) -> list[str]:
    """The loop that evaluates `jvp` (a lane copy) on the unit directions, four per call, one per
    lane, handing each lane's column `c` (rows `r`, value `v[l]`) to the `store` lines."""
    return [
        f"    for g in 0..{calls} {{",
        "        let d: [Pack; 2 * DOF] = core::array::from_fn(|c| {",
        f"            Pack::new(core::array::from_fn(|l| if c == {LANES} * g + l {{ 1.0 }} else {{ 0.0 }}))",
        "        });",
        "        let mut col = [Pack::splat(0.0); DOF];",
        f"        {jvp}::<Pack, true>(&t, &q, &dq, &ddq, &theta, &d, &mut col);",
        "        for r in 0..DOF {",
        "            let v = col[r].to_array();",
        f"            for l in 0..{LANES}.min(2 * DOF - {LANES} * g) {{",
        f"                let c = {LANES} * g + l;",
        *[f"                {ln}" for ln in store],
        "            }",
        "        }",
        "    }",
    ]


_SPLAT = (
    "    let (t, q, dq, ddq, theta) = (t.map(Pack::splat), q.map(Pack::splat), dq.map(Pack::splat),"
    " ddq.map(Pack::splat), theta.map(Pack::splat));"
)


def _compact(arm: DhTable, k: Kernel, fused: str) -> str:
    """`forward_dynamics_derivatives` as less code per call (docs/derivatives.md: the fused kernel
    is bound by instruction fetch). With AVX: `q̈` and `M⁻¹` from one straight-line part, the
    columns of `(∂τ/∂q, ∂τ/∂q̇)` from the directional-derivative part of inverse dynamics evaluated
    on four unit directions at once (its lane copy, one direction per lane, `⌈2n/4⌉` calls), then
    `∂q̈/∂x = −M⁻¹ ∂τ/∂x` in a loop. Without AVX, and in the lane forms, the fused straight-line
    kernel `<kernel>_fused`."""
    n, name = arm.dof, k.name
    parts = [_emit_part(name, p) for p in k.parts]
    used = sorted({int(j) for trig, _ in parts for j in trig.split(",") if j})
    fdm, jvp = (e for _, e in parts)
    calls = _calls(n)
    t = ", ".join(f"c{i + 1}, s{i + 1}" if i in used else "0.0, 0.0" for i in range(n))
    sig = ", ".join(k.args + [f"out: &mut [f64; {k.out_len}]"])
    args = "q, dq, tau, theta, out"
    ops = (
        f"part_fdm {fdm.mul} / {fdm.add}, part_jvp {jvp.mul} / {jvp.add} ({calls} calls of {LANES} lanes), "
        f"and the {2 * n}·{n}² products"
    )
    doc = f"/// Compact scalar form ({ops}): with AVX `{name}_wide`, else `{name}_fused`."
    head = (
        _dispatch(doc, name, sig, args)
        + f"""
/// `q̈` and `M⁻¹` (`{name}_part_fdm`), `∂τ/∂x` four unit directions per call
/// (`{name}_part_jvp_lanes`), `∂q̈/∂x = −M⁻¹ ∂τ/∂x`.
{_AVX_CFG}
#[inline(never)]
fn {name}_wide({sig}) {{
    use crate::pack::Pack;
"""
    )
    body = [f"    {ln}" for ln in _trig_prelude(arm, used)]
    body += [
        f"    let t = [{t}];",
        "    let mut a = [0.0; DOF + DOF * DOF];",
        f"    {name}_part_fdm(&t, q, dq, tau, theta, &mut a);",
        "    let ddq: [f64; DOF] = core::array::from_fn(|i| a[i]);",
        _SPLAT,
        "    // j[r][c] = ∂τ_r/∂x_c, x = (q, q̇).",
        "    let mut j = [[0.0; 2 * DOF]; DOF];",
        *_columns(f"{name}_part_jvp_lanes", calls, ["j[r][c] = v[l];"]),
        "    for r in 0..DOF {",
        "        for c in 0..2 * DOF {",
        "            let mut acc = 0.0;",
        "            for k in 0..DOF {",
        "                acc = crate::trig::mul_add(a[DOF + r * DOF + k], j[k][c], acc);",
        "            }",
        "            out[(c / DOF) * DOF * DOF + r * DOF + c % DOF] = -acc;",
        "        }",
        "    }",
        "    out[2 * DOF * DOF..].copy_from_slice(&a[DOF..]);",
        "}",
    ]
    fused = fused.replace(f"pub fn {name}(", f"pub fn {name}_fused(", 1)
    return "\n\n".join([head + "\n".join(body), fused, fdm.code, jvp.code])


def _compact_id(dof: int, emitted: list[Emitted]) -> list[Emitted]:
    """Where `forward_dynamics_derivatives` has its compact form, `inverse_dynamics_derivatives`
    gets one from the same directional-derivative part: with AVX its `⌈2n/4⌉` four-lane calls on
    the unit directions are the columns of `(∂τ/∂q, ∂τ/∂q̇)`, less code per call than the
    straight-line kernel (which stays as `inverse_dynamics_derivatives_fused`)."""
    by = {e.name: e for e in emitted}
    fdd, idd = by.get("forward_dynamics_derivatives"), by.get("inverse_dynamics_derivatives")
    if fdd is None or idd is None or "fn forward_dynamics_derivatives_wide(" not in fdd.code:
        return emitted
    if idd.mul + idd.add < COMPACT_MIN_OPS:
        return emitted
    wide = fdd.code.split("fn forward_dynamics_derivatives_wide(", 1)[1]
    lines = wide.splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.strip().startswith("use crate::pack::Pack"))
    end = next(i for i, ln in enumerate(lines) if ln.strip().startswith("let t = ["))
    setup = lines[start + 1 : end + 1]
    name, jvp = idd.name, "forward_dynamics_derivatives_part_jvp_lanes"
    n_calls = _calls(dof)
    sig = "q: &[f64; DOF], dq: &[f64; DOF], ddq: &[f64; DOF], theta: &[f64; NB], out: &mut [f64; 2 * DOF * DOF]"
    args = "q, dq, ddq, theta, out"
    doc = (
        f"/// Compact scalar form (`{jvp}`, {n_calls} calls of {LANES} lanes on unit directions): with\n"
        f"/// AVX `{name}_wide`, else `{name}_fused`."
    )
    store = ["out[(c / DOF) * DOF * DOF + r * DOF + c % DOF] = v[l];"]
    code = (
        _dispatch(doc, name, sig, args)
        + f"""
/// `(∂τ/∂q, ∂τ/∂q̇)`, four columns per call of `{jvp}` (one unit direction per lane).
{_AVX_CFG}
#[inline(never)]
fn {name}_wide({sig}) {{
    use crate::pack::Pack;
"""
        + "\n".join(setup + [_SPLAT, *_columns(jvp, n_calls, store), "}"])
        + "\n\n"
        + idd.code.replace(f"pub fn {name}(", f"pub fn {name}_fused(", 1)
    )
    return [Emitted(e.name, code, e.mul, e.add) if e is idd else e for e in emitted]


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

    pre = _trig_prelude(arm, trig_joints, body.mul + body.add < EIGHT_MAX_OPS)
    sig = ", ".join(k.args + [f"out: &mut [f64; {k.out_len}]"])
    lines = [f"#[inline]\npub fn {k.name}({sig}) {{"]
    lines += [f"    {ln}" for ln in pre + body.lines]
    lines.append("}")
    code = "\n".join(lines)
    if k.parts and body.mul + body.add >= COMPACT_MIN_OPS:
        code = _compact(arm, k, code)
    return Emitted(k.name, code, body.mul, body.add)


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
    emitted = _compact_id(arm.dof, emitted)
    text = render(arm, toml_path.name, digest, base, emitted)
    ops = [(e.name, e.mul, e.add) for e in emitted]
    return Result(arm.name, text, time.perf_counter() - t0, ops, base.rank, lag)
