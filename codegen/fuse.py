"""Fused multiply-adds: a product read once, by a sum or difference, folded into it.

`let p = a * b; … let s = p + c;` becomes `let s = crate::trig::mul_add(a, b, c);` (and `c + p`,
`p - c`, `c - p` likewise, with the negation on `c`, `a` or a literal), the product's statement
removed. `crate::trig::mul_add` is one fused instruction (one rounding) where the target has FMA
and the two operations otherwise; the lane copies call the lane type's form of it, so every lane
stays bit for bit the scalar kernel. This is what a C compiler does to SymPyBotics' output under
GCC's default `-ffp-contract=fast`: the Panda mass matrix's 985 operations become 640
instructions. The values change in their last bits (one rounding fewer per fused pair), not in
what is computed; the operation counts stay those of the expressions.
"""

from __future__ import annotations

import re

# The statement grammar of an emitted body (shared by `reassociate` and `schedule`).
LET = re.compile(r"^let (x\d+) = (.*);$")
PRODUCT = re.compile(r"^(\S+) \* (\S+)$")
SUM = re.compile(r"^(\S+) ([+-]) (\S+)$")
REF = re.compile(r"\bx\d+\b")
_LITERAL = re.compile(r"^\(?-?[0-9][0-9.eE+-]*\)?$")

MUL_ADD = "crate::trig::mul_add"


def negate(operand: str) -> str:
    """`-operand`, as Rust source: a literal's sign flipped in the text (`0.5` ↔ `(-0.5)`), a
    leading minus dropped."""
    if _LITERAL.match(operand):
        text = operand.strip("()")
        return text[1:] if text.startswith("-") else f"({'-' + text})"
    return operand[1:] if operand.startswith("-") else f"-{operand}"


def fuse(lines: list[str]) -> list[str]:
    """`lines` (`let xN = …;` and `out[i] = …;`, each value defined before use) with every product
    read only once, by a `+` or `-`, folded into that statement as a `mul_add` (of two single-use
    products in one sum, the first operand's)."""
    uses: dict[str, int] = {}
    products: dict[str, tuple[str, str]] = {}
    for ln in lines:
        m = LET.match(ln)
        rhs = m.group(2) if m else ln.split(" = ", 1)[1]
        for r in REF.findall(rhs):
            uses[r] = uses.get(r, 0) + 1
        if m and (p := PRODUCT.match(m.group(2))):
            products[m.group(1)] = (p.group(1), p.group(2))
    folded: set[str] = set()
    out: list[str] = []
    for ln in lines:
        m = LET.match(ln)
        s = SUM.match(m.group(2)) if m else None
        if s:
            left, op, right = s.groups()
            single = [x for x in (left, right) if x in products and uses.get(x) == 1 and x not in folded]
            if single:
                p = single[0]
                a, b = products[p]
                if p == left:  # a·b + right, a·b − right
                    c = right if op == "+" else negate(right)
                else:  # left + a·b, left − a·b
                    c = left
                    a = a if op == "+" else negate(a)
                folded.add(p)
                ln = f"let {m.group(1)} = {MUL_ADD}({a}, {b}, {c});"
        out.append(ln)
    return [ln for ln in out if not ((m := LET.match(ln)) and m.group(1) in folded)]
