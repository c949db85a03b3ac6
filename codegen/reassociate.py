"""Sums re-associated by when their terms are ready, with their single-use products fused in.

A straight-line Newton–Euler kernel is a chain of rotations, link after link, longer than the
CPU's reorder window, so a call runs at the speed of its longest dependency chain more than of its
operation count. CasADi builds every sum in the order the recursion wrote it, so a term that
arrives late (the previous link's value) often enters first and the rest of the sum waits for it.
Here each maximal tree of `+`, `−` and negations (each inner node read only by the tree) is
flattened into signed terms and rebuilt as Huffman's algorithm would on the terms' ready times:
the two earliest are combined first, so the latest-ready term enters last. A product read only
by the tree becomes a fused multiply-add there: `let s = crate::trig::mul_add(a, b, c);` for
`a·b + c` (negations on `c`, `a` or a literal), one instruction and one rounding where the target
has FMA (the lane copies call `Lane::mul_add`, the same value per lane) — what GCC does to
SymPyBotics' C under its default `-ffp-contract=fast`.

Ready times: inputs at 0, the joints' cosines and sines at `TRIG` (one evaluation of the
sine/cosine polynomial), `+ − ×` after 3 cycles, a fused multiply-add after 4, a negation after 1,
a division after 13.
The values change in their last bits (another order of the same terms, one rounding fewer per
fused pair); the operation counts stay those of the expressions.
"""

from __future__ import annotations

import heapq
import re

from .fuse import LET, MUL_ADD, PRODUCT, REF, SUM, negate

_NEG = re.compile(r"^-(x\d+)$")
_TRIG = re.compile(r"^[sc]\d+$")
_OPERAND = re.compile(r"[^\s*/+(),-]+")

ADD, MUL, FMA, NEG, DIV = 3, 3, 4, 1, 13
TRIG = 40

# A term of a sum: (ready time, tie-break, sign, value or "", the product's factors or None).
Term = tuple[int, int, int, str, tuple[str, str] | None]


def _when(ready: dict[str, int], v: str) -> int:
    v = v.strip("()").lstrip("-")
    return TRIG if _TRIG.match(v) else ready.get(v, 0)


def _cost(e: str) -> int:
    if e.startswith(MUL_ADD):
        return FMA
    return NEG if _NEG.match(e) else MUL if PRODUCT.match(e) else DIV if " / " in e else ADD


def critical_path(lines: list[str]) -> int:
    """Cycles of the longest chain of dependent operations in `lines` (the latencies above)."""
    ready: dict[str, int] = {}
    for ln in lines:
        if m := LET.match(ln):
            e = m.group(2)
            operands = _OPERAND.findall(e.removeprefix(MUL_ADD))
            ready[m.group(1)] = _cost(e) + max((_when(ready, r) for r in operands), default=0)
    return max(ready.values(), default=0)


def _absorbed(lines: list[str]) -> dict[str, str]:
    """The statements that join the sum tree reading them (name → expression): sums, negations
    and products read once, by a sum or by a negation that joins one."""
    defs: dict[str, str] = {}
    uses: dict[str, int] = {}
    for ln in lines:
        m = LET.match(ln)
        for r in REF.findall(m.group(2) if m else ln.split(" = ", 1)[1]):
            uses[r] = uses.get(r, 0) + 1
        if m:
            defs[m.group(1)] = m.group(2)
    inner: dict[str, str] = {}
    for ln in reversed(lines):  # a statement's readers come after it
        m = LET.match(ln)
        if not m or not (SUM.match(m.group(2)) or (_NEG.match(m.group(2)) and m.group(1) in inner)):
            continue
        for r in REF.findall(m.group(2)):
            e = defs.get(r, "")
            if uses[r] == 1 and (SUM.match(e) or _NEG.match(e) or PRODUCT.match(e)):
                inner[r] = e
    return inner


def reassociate(lines: list[str]) -> list[str]:
    """`lines` (`let xN = …;` and `out[i] = …;`, binary operations and negations, each value
    defined before use) with every sum tree rebuilt by ready time and its single-use products
    fused; the tree's value keeps its name, new inner values get fresh ones."""
    inner = _absorbed(lines)
    ready: dict[str, int] = {}
    fresh = [1 + max((int(m.group(1)[1:]) for ln in lines if (m := LET.match(ln))), default=0)]
    out: list[str] = []

    def when(v: str) -> int:
        return _when(ready, v)

    def terms(v: str, sign: int, acc: list[tuple[int, str, tuple[str, str] | None]]) -> None:
        e = inner.get(v)
        if e and (s := SUM.match(e)):
            terms(s.group(1), sign, acc)
            terms(s.group(3), sign if s.group(2) == "+" else -sign, acc)
        elif e and (n := _NEG.match(e)):
            terms(n.group(1), -sign, acc)
        elif e and (p := PRODUCT.match(e)):
            acc.append((sign, "", (p.group(1), p.group(2))))
        else:
            acc.append((sign, v, None))

    def let(name: str | None, expr: str, at: int) -> str:
        if name is None:
            name = f"x{fresh[0]}"
            fresh[0] += 1
        out.append(f"let {name} = {expr};")
        ready[name] = at
        return name

    def rebuild(name: str, e: str) -> None:
        s = SUM.match(e)
        flat: list[tuple[int, str, tuple[str, str] | None]] = []
        terms(s.group(1), 1, flat)
        terms(s.group(3), 1 if s.group(2) == "+" else -1, flat)
        heap: list[Term] = [
            (max(when(p[0]), when(p[1])) if p else when(v), i, sign, v, p) for i, (sign, v, p) in enumerate(flat)
        ]
        heapq.heapify(heap)
        order = len(heap)
        while len(heap) > 1:
            t1, _, s1, v1, p1 = heapq.heappop(heap)
            t2, _, s2, v2, p2 = heapq.heappop(heap)
            root = name if not heap else None
            if p1 and p2:  # two products: the earlier one multiplied, the later fused onto it
                v1, t1, p1 = let(None, f"{p1[0]} * {p1[1]}", t1 + MUL), t1 + MUL, None
            if p1:
                (t1, s1, v1, p1), (t2, s2, v2, p2) = (t2, s2, v2, p2), (t1, s1, v1, p1)
            if p2:  # s1·(v1 ± a·b)
                a, b = p2
                a = a if s1 == s2 else negate(a)
                at, sign = max(t1, t2) + FMA, s1
                if root and sign < 0:  # −(v1 + a·b) = (−a)·b − v1: the tree's value positive
                    a, v1, sign = negate(a), negate(v1), 1
                expr = f"{MUL_ADD}({a}, {b}, {v1})"
            else:
                at = max(t1, t2) + ADD
                if s1 == s2:
                    expr, sign = f"{v1} + {v2}", s1
                else:
                    expr, sign = (f"{v1} - {v2}", 1) if s1 > 0 else (f"{v2} - {v1}", 1)
                if root and sign < 0:  # −(v1 + v2)
                    expr, sign, at = f"-{let(None, expr, at)}", 1, at + NEG
            heapq.heappush(heap, (at, order, sign, let(root, expr, at), None))
            order += 1

    for ln in lines:
        m = LET.match(ln)
        if not m:
            out.append(ln)
        elif m.group(1) in inner:
            continue
        elif SUM.match(m.group(2)):
            rebuild(*m.groups())
        else:
            out.append(ln)
            e = m.group(2)
            ready[m.group(1)] = _cost(e) + max((when(r) for r in _OPERAND.findall(e)), default=0)
    return out
