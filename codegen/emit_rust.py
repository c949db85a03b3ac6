"""CasADi expression graph -> straight-line Rust (one `let` per operation) and its operation count.

Operations are counted the way SymPyBotics' numbers are quoted: binary `*` and `/` (and x², 2x) as
multiplications, binary `+` and `-` as additions; negation is free.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca

from .fuse import fuse
from .reassociate import critical_path, reassociate
from .schedule import schedule

# A body with more operations per cycle of its longest dependency chain than this is bound by
# throughput (Zen 4 has four floating-point pipes), not latency: the regressors and the derivatives.
# It keeps CasADi's association (`fuse`), which keeps fewer values live; re-associated by ready time,
# the Panda base regressor spilled 40 % more and ran 0.89x [0.89-0.90] (3 interleaved rounds).
LATENCY_BOUND = 4

BINARY = {ca.OP_ADD: "+", ca.OP_SUB: "-", ca.OP_MUL: "*", ca.OP_DIV: "/"}
MULS = {ca.OP_MUL, ca.OP_DIV, ca.OP_SQ, ca.OP_TWICE, ca.OP_INV}
ADDS = {ca.OP_ADD, ca.OP_SUB}


@dataclass
class Body:
    lines: list[str]
    mul: int
    add: int
    used: set[tuple[int, int]]  # (input index, element) actually read


def literal(x: float) -> str:
    if x == 0.0:
        return "0.0"
    text = repr(float(x))
    if "e" not in text and "." not in text and "inf" not in text:
        text += ".0"
    return f"({text})" if x < 0 else text


def emit(
    f: ca.Function, input_name: Callable[[int, int], str], n_out: int, out: str = "out", reorder: bool = True
) -> Body:
    """Body of a Rust function evaluating f's single output into `out[0..n_out]`, single-use
    products fused into the sums that read them: those sums re-associated by ready time
    (`reassociate`) where the body is bound by latency, else in CasADi's association (`fuse`); its
    statements in the order of `schedule` (CasADi's with `reorder=False`)."""
    slot: dict[int, str] = {}
    lines: list[str] = []
    written: set[int] = set()
    used: set[tuple[int, int]] = set()
    n_mul = n_add = 0
    counter = 0

    # Value numbering up to commutativity: CasADi's `cse` merges only identical operand orders, so
    # `a * b` and `b * a` (or `a + b`, `b + a`) were emitted twice. IEEE addition and
    # multiplication are exactly commutative, so reusing the first changes no value.
    known: dict[tuple[str, ...], str] = {}

    def fresh(expr: str, key: tuple[str, ...]) -> tuple[str, bool]:
        nonlocal counter
        if key in known:
            return known[key], False
        name = f"x{counter}"
        counter += 1
        lines.append(f"let {name} = {expr};")
        known[key] = name
        return name, True

    def binary(sym: str, a: str, b: str) -> tuple[str, bool]:
        key = (sym, *sorted((a, b))) if sym in ("+", "*") else (sym, a, b)
        return fresh(f"{a} {sym} {b}", key)

    for k in range(f.n_instructions()):
        op = f.instruction_id(k)
        ins = f.instruction_input(k)
        outs = f.instruction_output(k)
        if op == ca.OP_INPUT:
            used.add((ins[0], ins[1]))
            slot[outs[0]] = input_name(ins[0], ins[1])
        elif op == ca.OP_CONST:
            slot[outs[0]] = literal(f.instruction_constant(k))
        elif op == ca.OP_OUTPUT:
            idx = outs[1]
            lines.append(f"{out}[{idx}] = {slot[ins[0]]};")
            written.add(idx)
        elif op == ca.OP_ASSIGN:
            slot[outs[0]] = slot[ins[0]]
            continue
        else:
            if op in BINARY:
                name, new = binary(BINARY[op], slot[ins[0]], slot[ins[1]])
            elif op == ca.OP_NEG:
                name, new = fresh(f"-{slot[ins[0]]}", ("neg", slot[ins[0]]))
            elif op == ca.OP_SQ:
                name, new = binary("*", slot[ins[0]], slot[ins[0]])
            elif op == ca.OP_INV:
                name, new = binary("/", "1.0", slot[ins[0]])
            elif op == ca.OP_TWICE:
                name, new = binary("*", "2.0", slot[ins[0]])
            else:
                raise NotImplementedError(f"CasADi operation {op} has no Rust translation")
            slot[outs[0]] = name
            if new and op in MULS:
                n_mul += 1
            elif new and op in ADDS:
                n_add += 1
    for idx in range(n_out):
        if idx not in written:
            lines.append(f"{out}[{idx}] = 0.0;")
    fused = fuse(lines)
    lets = sum(ln.startswith("let ") for ln in fused)
    lines = reassociate(lines) if lets <= LATENCY_BOUND * critical_path(fused) else fused
    return Body(schedule(lines) if reorder else lines, n_mul, n_add, used)
