"""Checks the source layout rules of issue 16 and prints what breaks them.

- no file under src/ over 900 lines (test-only files — `tests.rs`, `*_tests.rs` — are exempt);
- no function over 120 lines outside `#[cfg(test)]` modules (report prose may be listed in ALLOW);
- no cycle between the top-level modules of src/ (`crate::a` naming `crate::b` in either direction,
  counting every `crate::x` path in code, not in comments).

    python3 scripts/structure.py                   # exit 1 and a list when a rule is broken
    python3 scripts/structure.py --warn-functions  # long functions listed, not counted (CI, until
                                                   # the last ones are split: see docs/ARCHITECTURE.md)

Brace counting is enough for this code base: string literals with unbalanced braces are not used in
function bodies that matter here, and a miscount shows up as an absurd length that one would look at.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
MAX_FILE = 900
MAX_FN = 120
ALLOW: set[str] = set()  # "path::fn" of prose-only report functions allowed to be longer

FN = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?(?:const\s+)?(?:unsafe\s+)?fn\s+(\w+)")
CRATE = re.compile(r"\bcrate::(\w+)")


def strip_comment(line: str) -> str:
    i = line.find("//")
    return line if i < 0 else line[:i]


def top_module(path: Path) -> str:
    rel = path.relative_to(SRC).parts
    return rel[0].removesuffix(".rs") if rel else ""


def is_test_file(path: Path) -> bool:
    return path.name == "tests.rs" or path.name.endswith("_tests.rs")


def long_functions(path: Path, lines: list[str]) -> list[str]:
    out = []
    depth = 0
    test_depth = None  # brace depth at which a #[cfg(test)] module opened
    pending_test = False
    open_fns: list[tuple[str, int, int]] = []  # (name, start line, depth before its body)
    for n, raw in enumerate(lines, 1):
        line = strip_comment(raw)
        if "#[cfg(test)]" in line:
            pending_test = True
        m = FN.match(line)
        if m and test_depth is None:
            open_fns.append((m.group(1), n, depth))
        for ch in line:
            if ch == "{":
                if pending_test and test_depth is None:
                    test_depth = depth
                    pending_test = False
                depth += 1
            elif ch == "}":
                depth -= 1
                if test_depth is not None and depth == test_depth:
                    test_depth = None
                while open_fns and depth == open_fns[-1][2]:
                    name, start, _ = open_fns.pop()
                    length = n - start + 1
                    key = f"{path.relative_to(SRC.parent)}::{name}"
                    if length > MAX_FN and key not in ALLOW:
                        out.append(f"{key}: function of {length} lines (max {MAX_FN}), line {start}")
        if m and "{" not in line and line.rstrip().endswith(";") and open_fns and open_fns[-1][1] == n:
            open_fns.pop()  # a declaration without a body (trait method)
    return out


def main() -> int:
    warn_functions = "--warn-functions" in sys.argv[1:]
    problems: list[str] = []
    warnings: list[str] = []
    edges: dict[str, set[str]] = {}
    for path in sorted(SRC.rglob("*.rs")):
        text = path.read_text(encoding="utf-8")
        lines = text.splitlines()
        rel = path.relative_to(SRC.parent)
        if len(lines) > MAX_FILE and not is_test_file(path):
            problems.append(f"{rel}: {len(lines)} lines (max {MAX_FILE})")
        (warnings if warn_functions else problems).extend(long_functions(path, lines))
        me = top_module(path)
        for line in lines:
            for other in CRATE.findall(strip_comment(line)):
                if other != me and ((SRC / f"{other}.rs").exists() or (SRC / other).is_dir()):
                    edges.setdefault(me, set()).add(other)
    # Cycles between top-level modules (depth-first search).
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for o in sorted(edges.get(m, ())):
            if state.get(o) == 1:
                problems.append("module cycle: " + " -> ".join(stack[stack.index(o) :] + [o]))
            elif o not in state:
                visit(o)
        stack.pop()
        state[m] = 2

    for m in sorted(edges):
        if m not in state:
            visit(m)
    for w in warnings:
        print(f"warning: {w}")
    for p in problems:
        print(p)
    print(f"structure: {len(problems)} problem(s) in {SRC}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
