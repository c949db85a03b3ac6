"""Checks the workspace's source layout rules and prints what breaks them.

In every crate of the workspace (each `Cargo.toml` with a `src/` beside it):
- no file over 900 lines (test-only files — `tests.rs`, `*_tests.rs` — are exempt);
- no function over 120 lines outside `#[cfg(test)]` code;
- no cycle between files: a file names another through `crate::`, `super::` or `self::` paths (in `use`
  trees or in code, not in comments or tests), each path resolved to the deepest module file it reaches (a
  `mod.rs` that re-exports its children with bare `pub use child::X` is their facade, not a dependency).

    python3 scripts/structure.py    # exit 1 and the offenders when a rule is broken

Brace counting is enough for this code base: string literals with unbalanced braces are not used in
function bodies that matter here, and a miscount shows up as an absurd length that one would look at.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MAX_FILE = 900
MAX_FN = 120

FN = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?(?:const\s+)?(?:async\s+)?(?:unsafe\s+)?fn\s+(\w+)")
PATH = re.compile(r"\b(crate|super|self)((?:\s*::\s*\w+)+)")
USE = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?use\s+([^;]*);", re.S | re.M)


def crates() -> list[Path]:
    """The `src/` directories of the workspace's crates."""
    out = []
    for toml in sorted(ROOT.glob("**/Cargo.toml")):
        rel = toml.relative_to(ROOT).parts
        if any(p in {"target", ".venv", "node_modules"} or p.startswith(".") for p in rel):
            continue
        if (toml.parent / "src").is_dir():
            out.append(toml.parent / "src")
    return out


def strip_comment(line: str) -> str:
    i = line.find("//")
    return line if i < 0 else line[:i]


def module_of(src: Path, path: Path) -> tuple[str, ...]:
    parts = list(path.relative_to(src).parts)
    last = parts.pop()
    if last not in {"lib.rs", "main.rs", "mod.rs"}:
        parts.append(last.removesuffix(".rs"))
    return tuple(parts)


def is_test_file(path: Path) -> bool:
    return path.name == "tests.rs" or path.name.endswith("_tests.rs")


def scan(rel: str, lines: list[str]) -> tuple[list[str], list[str]]:
    """Functions over MAX_FN lines, and the code lines outside `#[cfg(test)]` items."""
    long = []
    code = []
    depth = 0
    test_depth = None  # brace depth at which a #[cfg(test)] item opened
    pending_test = False
    open_fns: list[tuple[str, int, int]] = []  # (name, start line, depth before its body)
    for n, raw in enumerate(lines, 1):
        line = strip_comment(raw)
        if "#[cfg(test)]" in line:
            pending_test = True
        if test_depth is None and not pending_test:
            code.append(line)
        elif pending_test and test_depth is None and line.strip().endswith(";"):
            pending_test = False  # `#[cfg(test)] mod tests;` or a test-only `use`
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
                    if length > MAX_FN:
                        long.append(f"{rel}::{name}: function of {length} lines (max {MAX_FN}), line {start}")
        if m and "{" not in line and line.rstrip().endswith(";") and open_fns and open_fns[-1][1] == n:
            open_fns.pop()  # a declaration without a body (trait method)
    return long, code


def expand(tree: str) -> list[str]:
    """`a::{b, c::{d, e}}` → `a::b`, `a::c::d`, `a::c::e` (whitespace removed, renames dropped)."""
    tree = re.sub(r"\s+", "", re.sub(r"\s+as\s+\w+", "", tree))
    i = tree.find("{")
    if i < 0:
        return [tree]
    prefix, body = tree[:i], tree[i + 1 : tree.rfind("}")]
    parts, level, cur = [], 0, ""
    for ch in body:
        if ch == "," and level == 0:
            parts.append(cur)
            cur = ""
            continue
        level += ch == "{"
        level -= ch == "}"
        cur += ch
    parts.append(cur)
    return [x for p in parts if p for x in expand(prefix + p)]


def resolve(me: tuple[str, ...], path: list[str], modules: set[tuple[str, ...]]) -> tuple[str, ...]:
    """The deepest module that `path` (starting with crate, super or self) reaches."""
    base, rest = ((), path[1:]) if path[0] == "crate" else (me, path)
    while rest and rest[0] in {"self", "super"}:
        if rest[0] == "super":
            base = base[:-1]
        rest = rest[1:]
    for seg in rest:
        if seg == "self":
            continue
        if base + (seg,) in modules:
            base = base + (seg,)
        else:
            break
    return base


def cycles(edges: dict[tuple[str, ...], set[tuple[str, ...]]], files: dict[tuple[str, ...], Path]) -> list[str]:
    """Every cycle a depth-first search meets, as a chain of file paths."""
    out: list[str] = []
    state: dict[tuple[str, ...], int] = {}
    stack: list[tuple[str, ...]] = []

    def visit(m: tuple[str, ...]) -> None:
        state[m] = 1
        stack.append(m)
        for o in sorted(edges.get(m, ())):
            if state.get(o) == 1:
                cycle = stack[stack.index(o) :] + [o]
                out.append("file cycle: " + " -> ".join(str(files[c].relative_to(ROOT)) for c in cycle))
            elif o not in state:
                visit(o)
        stack.pop()
        state[m] = 2

    for m in sorted(edges):
        if m not in state:
            visit(m)
    return out


def main() -> int:
    problems: list[str] = []
    for src in crates():
        files = {module_of(src, p): p for p in sorted(src.rglob("*.rs"))}
        modules = set(files)
        edges: dict[tuple[str, ...], set[tuple[str, ...]]] = {}
        for me, path in files.items():
            rel = str(path.relative_to(ROOT))
            lines = path.read_text(encoding="utf-8").splitlines()
            if len(lines) > MAX_FILE and not is_test_file(path):
                problems.append(f"{rel}: {len(lines)} lines (max {MAX_FILE})")
            long, code = scan(rel, lines)
            problems.extend(long)
            text = "\n".join(code)
            refs: list[list[str]] = []
            for tree in USE.findall(text):
                for p in expand(tree):
                    segs = [s for s in p.split("::") if s and s != "*"]
                    if segs and segs[0] in {"crate", "super", "self"}:
                        refs.append(segs)
            body = USE.sub("", text)
            for head, tail in PATH.findall(body):
                refs.append([head, *[s for s in re.sub(r"\s+", "", tail).split("::") if s]])
            for segs in refs:
                target = resolve(me, segs, modules)
                if target != me and target in modules:
                    edges.setdefault(me, set()).add(target)

        problems.extend(cycles(edges, files))
    for p in problems:
        print(p)
    print(f"structure: {len(problems)} problem(s) in {len(crates())} crates")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
