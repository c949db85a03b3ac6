"""Specifications of the generator, checked against independent oracles.

Oracles: the paper's closed-form regressor of the 2-DOF arm, the Lagrange equations derived by CasADi's
algorithmic differentiation of T - V, and identities between kernels (Y p = Yb theta = M ddq + h).
"""

from __future__ import annotations

import math
import re
import time
from fractions import Fraction
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from codegen import __main__ as cli
from codegen.base_params import analyse, random_states
from codegen.dh import DhError, load
from codegen.generate import _sx, derive, generate, source_hash
from codegen.kernels import INPUT_LEN, KERNELS, MANIFEST, manifest
from codegen.lagrange import lagrange_function

ROOT = Path(__file__).resolve().parents[2]
ARMS = sorted(p.stem for p in (ROOT / "arms").glob("*.toml"))


def kernels_of(name: str):
    arm = load(ROOT / "arms" / f"{name}.toml")
    base = analyse(arm)
    sym, theta, kernels = derive(arm, base)
    vec = {"trig": sym.trig, "q": sym.q, "dq": sym.dq, "ddq": sym.ddq, "tau": sym.tau, "theta": theta}
    fns = {k.name: ca.Function(k.name, [vec[v] for v in k.inputs], [_sx(k.outputs)]) for k in kernels}
    return arm, base, fns


def trig_of(arm, q):
    ang = q + np.array([j.theta for j in arm.joints])
    t = np.empty(2 * arm.dof)
    t[0::2], t[1::2] = np.cos(ang), np.sin(ang)
    return t


def base_map(base, n):
    B = np.zeros((base.rank, 10 * n))
    for r, c, v in base.entries:
        B[r, c] += v
    return B


def test_planar2_base_regressor_is_the_papers_phi():
    arm, base, f = kernels_of("planar2")
    assert base.exprs == ["ZZ1 + a1²·M2", "MX1 + a1·M2", "MY1", "ZZ2", "MX2", "MY2"]
    a1, g = 1.0, 9.81
    rng = np.random.default_rng(1)
    for _ in range(50):
        q, dq, ddq = rng.uniform(-np.pi, np.pi, 2), rng.uniform(-2, 2, 2), rng.uniform(-5, 5, 2)
        c1, s1, c2, s2 = math.cos(q[0]), math.sin(q[0]), math.cos(q[1]), math.sin(q[1])
        c12, s12 = math.cos(q[0] + q[1]), math.sin(q[0] + q[1])
        phi = np.array(
            [
                [
                    ddq[0],
                    g * c1,
                    -g * s1,
                    ddq[0] + ddq[1],
                    a1 * (2 * ddq[0] + ddq[1]) * c2 - a1 * (2 * dq[0] + dq[1]) * dq[1] * s2 + g * c12,
                    -a1 * (2 * ddq[0] + ddq[1]) * s2 - a1 * (2 * dq[0] + dq[1]) * dq[1] * c2 - g * s12,
                ],
                [
                    0,
                    0,
                    0,
                    ddq[0] + ddq[1],
                    a1 * ddq[0] * c2 + a1 * dq[0] ** 2 * s2 + g * c12,
                    -a1 * ddq[0] * s2 + a1 * dq[0] ** 2 * c2 - g * s12,
                ],
            ]
        )
        yb = np.array(f["base_regressor"](trig_of(arm, q), q, dq, ddq)).reshape(2, 6)
        assert np.allclose(yb, phi, rtol=1e-12, atol=1e-12 * np.abs(phi).max())


@pytest.mark.parametrize("name", ARMS)
def test_newton_euler_equals_lagrange(name):
    arm, _, f = kernels_of(name)
    lag = lagrange_function(arm)
    q, dq, ddq = random_states(arm, 5, np.random.default_rng(3))
    n = arm.dof
    for s in range(5):
        y_ne = np.array(f["regressor"](trig_of(arm, q[s]), q[s], dq[s], ddq[s])).reshape(n, 10 * n)
        y_lg = np.array(lag(q[s], dq[s], ddq[s]))
        assert np.max(np.abs(y_ne - y_lg)) <= 1e-10 * (1 + np.abs(y_lg).max())


@pytest.mark.parametrize("name", ARMS)
def test_kernel_identities(name):
    """Y p = Yb (B p) = ID(B p) = M ddq + h; g = h(dq = 0); M symmetric positive definite."""
    arm, base, f = kernels_of(name)
    n, nb = arm.dof, base.rank
    rng = np.random.default_rng(5)
    B = base_map(base, n)
    q, dq, ddq = random_states(arm, 10, rng)
    for s in range(10):
        p = physical_params(rng, n)
        th = B @ p
        t = trig_of(arm, q[s])
        y = np.array(f["regressor"](t, q[s], dq[s], ddq[s])).reshape(n, 10 * n)
        yb = np.array(f["base_regressor"](t, q[s], dq[s], ddq[s])).reshape(n, nb)
        tau = y @ p
        scale = 1 + np.abs(tau).max()
        assert np.allclose(yb @ th, tau, atol=1e-10 * scale)
        assert np.allclose(np.array(f["inverse_dynamics"](t, q[s], dq[s], ddq[s], th)).ravel(), tau, atol=1e-10 * scale)
        M = np.array(f["mass_matrix"](t, q[s], th)).reshape(n, n)
        h = np.array(f["bias"](t, q[s], dq[s], th)).ravel()
        assert np.allclose(M @ ddq[s] + h, tau, atol=1e-10 * scale)
        assert np.allclose(M, M.T, atol=0)
        assert np.linalg.eigvalsh(M).min() > 0
        g = np.array(f["gravity"](t, q[s], th)).ravel()
        assert np.allclose(np.array(f["bias"](t, q[s], 0 * dq[s], th)).ravel(), g, atol=1e-10 * scale)


def physical_params(rng, n):
    """Random physically consistent link parameters about the link origins."""
    p = []
    for _ in range(n):
        m = rng.uniform(0.5, 5)
        c = rng.uniform(-0.2, 0.2, 3)
        A = rng.normal(size=(3, 3))
        Ic = A @ A.T * 0.05 + 0.01 * np.eye(3)
        Io = Ic + m * (c @ c * np.eye(3) - np.outer(c, c))
        p += [Io[0, 0], Io[0, 1], Io[0, 2], Io[1, 1], Io[1, 2], Io[2, 2], *(m * c), m]
    return np.array(p)


@pytest.mark.parametrize("name,rank", [("planar2", 6), ("puma560", 36), ("panda", 43), ("scara", 8)])
def test_base_parameter_count(name, rank):
    """Known counts: PUMA 560 without motor inertias has 36 base parameters, Panda 43."""
    assert analyse(load(ROOT / "arms" / f"{name}.toml")).rank == rank


def test_generation_is_deterministic_and_committed_files_are_fresh():
    for name in ARMS:
        path = ROOT / "arms" / f"{name}.toml"
        text = generate(path).text
        assert generate(path).text == text
        assert f"source-hash: {source_hash(path.read_bytes())}" in text
        committed = ROOT / "generated" / f"{name}.rs"
        assert committed.read_text(encoding="utf-8") == text, f"{committed} is stale: run python -m codegen"


def test_seven_dof_arm_generates_in_under_30_seconds():
    t0 = time.perf_counter()
    generate(ROOT / "arms" / "panda.toml")
    assert time.perf_counter() - t0 < 30


def test_puma_base_regressor_operation_budget():
    """Issue budget: <= 800 operations (SymPyBotics emits 624 * + 397 + = 1,021)."""
    ops = {k: (m, a) for k, m, a in generate(ROOT / "arms" / "puma560.toml").ops}
    m, a = ops["base_regressor"]
    assert m + a <= 800


def test_bad_tables_are_rejected_with_the_file_named(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "bad"\n[[joint]]\nkind = "spherical"\n')
    with pytest.raises(DhError, match="bad.toml: joint 1: kind"):
        load(bad)
    bad.write_text('name = "bad"\n[[joint]]\nalpha = "90deg"\n')
    with pytest.raises(DhError, match="alpha: expected a number"):
        load(bad)


def test_cli_check_mode_detects_stale_files(tmp_path, capsys):
    arms = tmp_path / "arms"
    out = tmp_path / "generated"
    arms.mkdir()
    (arms / "two.toml").write_text((ROOT / "arms" / "planar2.toml").read_text().replace('"planar2"', '"two"'))
    assert cli.main(["--arms-dir", str(arms), "--out-dir", str(out), "--check"]) == 1
    assert cli.main(["--arms-dir", str(arms), "--out-dir", str(out)]) == 0
    assert cli.main(["--arms-dir", str(arms), "--out-dir", str(out), "--check"]) == 0
    (arms / "two.toml").write_text((arms / "two.toml").read_text().replace("a = 1.0", "a = 0.5"))
    assert cli.main(["--arms-dir", str(arms), "--out-dir", str(out), "--check"]) == 1


def test_kernel_manifest_is_fresh_and_lists_the_generated_functions():
    """generated/kernels.toml is the list in codegen/kernels.py, and every arm defines exactly those
    (besides the helpers of a compact scalar form, codegen/FORMAT.md)."""
    assert (ROOT / "generated" / MANIFEST).read_text(encoding="utf-8") == manifest()
    assert len({k.name for k in KERNELS}) == len(KERNELS)
    helper = re.compile("(" + "|".join(k.name for k in KERNELS) + r")_(fused|part_\w+)$")
    for name in ARMS:
        text = (ROOT / "generated" / f"{name}.rs").read_text(encoding="utf-8")
        fns = [line.split("(")[0].removeprefix("pub fn ") for line in text.splitlines() if line.startswith("pub fn ")]
        assert [f for f in fns if not helper.match(f)] == [k.name for k in KERNELS] + ["base_params"]
        for k in KERNELS:
            args = "".join(f"{v}: &[f64; {INPUT_LEN[v]}], " for v in k.inputs)
            assert f"pub fn {k.name}({args}out: &mut [f64; {k.out_len}])" in text


def _python(stmt: str) -> str:
    """An emitted Rust statement as Python (the same infix syntax; `mul_add` a Python function)."""
    return stmt.replace("crate::trig::mul_add", "mul_add")


def _unfused(a: float, b: float, c: float) -> float:
    """`a·b + c` in two roundings: `mul_add` where the target has no FMA, and the value of the
    statements `fuse` replaced, bit for bit (negation is exact, `+` commutes)."""
    return a * b + c


def _fused(a: float, b: float, c: float) -> float:
    """`a·b + c` in one rounding (an FMA), from the exact rational value (`float(Fraction)` rounds
    correctly)."""
    return float(Fraction(a) * Fraction(b) + Fraction(c))


def test_emission_merges_operations_equal_up_to_commutativity():
    """`a*b` and `b*a` (and `a+b`, `b+a`) are one value: emitted once, counted once; a
    non-commutative pair (`a-b`, `b-a`) stays two. The emitted body evaluates to CasADi's values."""
    from codegen.emit_rust import emit

    x = ca.SX.sym("x", 3)
    a, b, c = x[0], x[1], x[2]
    outs = [a * b + c, c + b * a, a - b, b - a, a * a, a**2]
    f = ca.Function("f", [x], [ca.cse(_sx(outs))])
    body = emit(f, lambda _inp, nz: f"v[{nz}]", len(outs))
    text = "\n".join(body.lines)
    assert (body.mul, body.add) == (2, 3), text
    assign = dict(ln.rstrip(";").split(" = ") for ln in body.lines if ln.startswith("out["))
    assert assign["out[0]"] == assign["out[1]"] and assign["out[4]"] == assign["out[5]"], text
    assert assign["out[2]"] != assign["out[3]"], text
    # Evaluate the emitted lines as Python (the same infix syntax) against CasADi.
    v = [0.3, -1.7, 2.5]
    env: dict[str, object] = {"v": v, "out": [0.0] * len(outs)}
    for ln in body.lines:
        stmt = ln.rstrip(";").removeprefix("let ")
        exec(_python(stmt), {"mul_add": _unfused}, env)
    want = np.array(f(v)).ravel()
    assert np.array_equal(np.array(env["out"]), want), (env["out"], want)


def test_schedule_keeps_every_statement_and_value_and_lowers_register_pressure():
    """The register-pressure order (codegen/schedule.py) of the PUMA 560 inverse dynamics: the
    same statements, each after the values it reads, the same outputs bit for bit when run (as
    Python) as CasADi's order and CasADi's values, and fewer values live at once; a kernel whose
    values fit the registers (planar2's mass matrix) keeps CasADi's order."""
    import re

    from codegen.emit_rust import emit
    from codegen.fuse import LET, REF
    from codegen.schedule import REGISTERS, graph, max_live

    def bodies(arm_name, kernel):
        arm = load(ROOT / "arms" / f"{arm_name}.toml")
        sym, theta, kernels = derive(arm, analyse(arm))
        k = next(k for k in kernels if k.name == kernel)
        vectors = {"trig": sym.trig, "q": sym.q, "dq": sym.dq, "ddq": sym.ddq, "tau": sym.tau, "theta": theta}
        f = ca.Function(k.name, [vectors[v] for v in k.inputs], [ca.cse(_sx(k.outputs))])
        name = lambda inp, nz: f"{k.inputs[inp]}[{nz}]"  # noqa: E731
        return f, k, emit(f, name, len(k.outputs)).lines, emit(f, name, len(k.outputs), reorder=False).lines

    def live(lines):
        return max_live(*graph(lines), range(len(lines)))

    f, k, ordered, casadi = bodies("puma560", "inverse_dynamics")
    assert sorted(ordered) == sorted(casadi) and ordered != casadi
    seen: set[str] = set()
    for ln in ordered:
        m = LET.match(ln)
        assert set(REF.findall(m.group(2) if m else ln.split(" = ", 1)[1])) <= seen, ln
        if m:
            seen.add(m.group(1))
    assert live(ordered) < live(casadi), (live(ordered), live(casadi))

    rng = np.random.default_rng(3)
    inputs = {n: list(rng.uniform(-1.0, 1.0, size=f.size1_in(i))) for i, n in enumerate(k.inputs)}
    results = []
    for lines in (ordered, casadi):
        env = {**{n: list(v) for n, v in inputs.items()}, "out": [0.0] * len(k.outputs)}
        for ln in lines:
            exec(_python(re.sub(r"^let ", "", ln.rstrip(";"))), {"mul_add": _unfused}, env)
        results.append(env["out"])
    assert results[0] == results[1]
    want = np.array(f(*[inputs[n] for n in k.inputs])).ravel()
    assert np.allclose(results[0], want, rtol=1e-12, atol=1e-12)

    _, _, small, small_casadi = bodies("planar2", "mass_matrix")
    assert small == small_casadi and live(small) <= REGISTERS


def test_fuse_folds_each_single_use_product_into_its_sum_with_the_right_signs():
    """`fuse` (codegen/fuse.py): for `p + c`, `c + p`, `p − c`, `c − p` with a single-use product
    `p` (a literal factor among them), one `mul_add` each and no product statement left; a product
    read twice stays. Run as Python, the fused body is bit for bit CasADi's values when `mul_add`
    rounds twice (as without FMA), and within an ulp or so of them when it rounds once (an FMA,
    from exact rationals); the PUMA 560 mass matrix, where most products fold, within 1e-13."""
    from codegen.emit_rust import emit

    def run(body, mul_add, env):
        for ln in body:
            exec(_python(ln.rstrip(";").removeprefix("let ")), {"mul_add": mul_add}, env)
        return env["out"]

    x = ca.SX.sym("x", 4)
    a, b, c, d = x[0], x[1], x[2], x[3]
    shared = c * d
    outs = [a * b + c, c + a * d, b * c - a, d - 0.25 * b, shared + a, shared - b]
    f = ca.Function("f", [x], [ca.cse(_sx(outs))])
    lines = emit(f, lambda _inp, nz: f"v[{nz}]", len(outs), reorder=False).lines
    assert sum("mul_add" in ln for ln in lines) == 4, lines
    assert sum(" * " in ln for ln in lines) == 1, lines  # c·d, read twice
    v = [0.3, -1.7, 2.5, 1.1]
    want = list(np.array(f(v)).ravel())
    assert run(lines, _unfused, {"v": v, "out": [0.0] * len(outs)}) == want, lines
    assert np.allclose(run(lines, _fused, {"v": v, "out": [0.0] * len(outs)}), want, rtol=1e-15, atol=1e-15)

    arm = load(ROOT / "arms" / "puma560.toml")
    sym, theta, kernels = derive(arm, analyse(arm))
    k = next(k for k in kernels if k.name == "mass_matrix")
    vectors = {"trig": sym.trig, "q": sym.q, "dq": sym.dq, "ddq": sym.ddq, "tau": sym.tau, "theta": theta}
    g = ca.Function(k.name, [vectors[n] for n in k.inputs], [ca.cse(_sx(k.outputs))])
    body = emit(g, lambda inp, nz: f"{k.inputs[inp]}[{nz}]", len(k.outputs)).lines
    assert sum("mul_add" in ln for ln in body) > 50
    rng = np.random.default_rng(5)
    inputs = {n: list(rng.uniform(-1.0, 1.0, size=g.size1_in(i))) for i, n in enumerate(k.inputs)}
    want = np.array(g(*[inputs[n] for n in k.inputs])).ravel()
    for mul_add in (_unfused, _fused):
        env = {**{n: list(v) for n, v in inputs.items()}, "out": [0.0] * len(k.outputs)}
        assert np.allclose(run(body, mul_add, env), want, rtol=1e-13, atol=1e-13), mul_add.__name__


def test_reassociate_adds_the_latest_term_last_where_a_kernel_is_bound_by_latency(monkeypatch):
    """`reassociate` (codegen/reassociate.py): a term ready late (a chain of products) enters its
    sum last, whatever CasADi's order, the sum's single-use product fused; run as Python, within
    an ulp of CasADi's value. `emit` re-associates the PUMA 560 inverse dynamics (its longest
    dependency chain shorter, its values within 1e-13 of CasADi's) but keeps CasADi's association
    in its base regressor, bound by throughput."""
    from codegen import emit_rust
    from codegen.reassociate import critical_path

    def run(body, env):
        for ln in body:
            exec(_python(ln.rstrip(";").removeprefix("let ")), {"mul_add": _unfused}, env)
        return env["out"]

    x = ca.SX.sym("x", 4)
    a, b, c, d = x[0], x[1], x[2], x[3]
    f = ca.Function("f", [x], [ca.cse(_sx([(((a * b) * c) * d + a) + b * c]))])
    lines = emit_rust.emit(f, lambda _inp, nz: f"v[{nz}]", 1, reorder=False).lines
    # (a·b)·c, then a + b·c from the early terms, then the late product fused on last.
    assert [ln.split(" = ", 1)[1] for ln in lines] == [
        "v[0] * v[1];",
        "x0 * v[2];",
        "crate::trig::mul_add(v[1], v[2], v[0]);",
        "crate::trig::mul_add(x1, v[3], x6);",
        "x5;",
    ], lines
    v = [0.3, -1.7, 2.5, 1.1]
    assert np.allclose(run(lines, {"v": v, "out": [0.0]}), np.array(f(v)).ravel(), rtol=1e-15)

    arm = load(ROOT / "arms" / "puma560.toml")
    sym, theta, kernels = derive(arm, analyse(arm))
    vectors = {"trig": sym.trig, "q": sym.q, "dq": sym.dq, "ddq": sym.ddq, "tau": sym.tau, "theta": theta}
    for name, reassociated in (("inverse_dynamics", True), ("base_regressor", False)):
        k = next(k for k in kernels if k.name == name)
        g = ca.Function(k.name, [vectors[n] for n in k.inputs], [ca.cse(_sx(k.outputs))])

        def name_of(inp: int, nz: int, k=k) -> str:  # the kernels' names: c1, s1, … for the trigonometry
            if k.inputs[inp] == "trig":
                return f"{'c' if nz % 2 == 0 else 's'}{nz // 2 + 1}"
            return f"{k.inputs[inp]}[{nz}]"

        body = emit_rust.emit(g, name_of, len(k.outputs), reorder=False).lines
        with monkeypatch.context() as mp:
            mp.setattr(emit_rust, "LATENCY_BOUND", 0)
            written = emit_rust.emit(g, name_of, len(k.outputs), reorder=False).lines
        assert (body != written) == reassociated, name
        assert (critical_path(body) < critical_path(written)) == reassociated, name
        rng = np.random.default_rng(5)
        inputs = {n: list(rng.uniform(-1.0, 1.0, size=g.size1_in(i))) for i, n in enumerate(k.inputs)}
        want = np.array(g(*[inputs[n] for n in k.inputs])).ravel()
        env = {**{n: list(v) for n, v in inputs.items()}, "out": [0.0] * len(k.outputs)}
        env |= {name_of(0, j): t for j, t in enumerate(inputs.get("trig", []))}
        assert np.allclose(run(body, env), want, rtol=1e-13, atol=1e-13), name
