"""Order of the emitted statements: fewest live values (greedy list scheduling).

CasADi lists a function's operations depth first, output by output, which in a long kernel keeps
many values live at once: LLVM keeps most of the source order within the kernel's one basic
block, so they are spilled to the stack and reloaded (a third of a PUMA 560 kernel's
instructions were stack operands). Here the statements are re-ordered by greedy list
scheduling on register pressure: among the statements whose operands are ready, the one that
frees the most values (last uses of its operands, minus the value it defines) goes first; ties
keep CasADi's order; a kernel whose values fit in the registers keeps CasADi's order. Only the
order changes: every statement, and so every value, is the same.
"""

from __future__ import annotations

from .fuse import LET, REF

# Vector registers of x86-64 with AVX2 (xmm0–xmm15): a kernel whose values all fit keeps
# CasADi's order (nothing to spill, nothing to gain).
REGISTERS = 16


def schedule(lines: list[str]) -> list[str]:
    """`lines` (`let xN = …;` and `out[i] = …;` statements, each value defined before use)
    re-ordered to keep few values live."""
    deps, users = graph(lines)
    if max_live(deps, users, range(len(lines))) <= REGISTERS:
        return lines
    remaining = [len(u) for u in users]
    waiting = [len(ds) for ds in deps]
    ready = {i for i in range(len(lines)) if waiting[i] == 0}
    order = []

    def gain(i: int) -> int:
        if not deps[i] and not users[i]:
            return -len(lines)  # an output of an input or a constant: last, as CasADi has it
        freed = sum(1 for d in deps[i] if remaining[d] == 1)
        return freed - (1 if users[i] else 0)

    while ready:
        i = max(ready, key=lambda j: (gain(j), -j))
        ready.remove(i)
        order.append(i)
        for d in deps[i]:
            remaining[d] -= 1
        for u in users[i]:
            waiting[u] -= 1
            if waiting[u] == 0:
                ready.add(u)
    if len(order) != len(lines):
        raise AssertionError("schedule: the statements do not form a DAG")
    return [lines[i] for i in order]


def graph(lines: list[str]) -> tuple[list[list[int]], list[list[int]]]:
    """Per statement, the statements whose values it reads and those that read its value."""
    defines: dict[str, int] = {}
    deps: list[list[int]] = []
    for i, ln in enumerate(lines):
        m = LET.match(ln)
        rhs = m.group(2) if m else ln.split(" = ", 1)[1]
        deps.append(sorted({defines[r] for r in REF.findall(rhs) if r in defines}))
        if m:
            defines[m.group(1)] = i
    users: list[list[int]] = [[] for _ in lines]
    for i, ds in enumerate(deps):
        for d in ds:
            users[d].append(i)
    return deps, users


def max_live(deps: list[list[int]], users: list[list[int]], order) -> int:
    """Most values live at once when the statements run in `order`."""
    remaining = [len(u) for u in users]
    live = most = 0
    for i in order:
        for d in deps[i]:
            remaining[d] -= 1
            live -= remaining[d] == 0
        live += bool(users[i])
        most = max(most, live)
    return most
