"""The documentation's code blocks run, so the README and the guide cannot rot.

Every fenced block tagged `sh` or `python` in README.md and docs/*.md is run, top to bottom as a reader
would (a block may use what an earlier block of the same page wrote), in one scratch directory per page that
sees the repository's files (data/, docs/, arms/, ... linked in; outputs such as out/ land in the scratch
directory): `dynid` and `cargo run --release --` are the CLI that `cargo test` built (`$DYNID_CLI`), Python
blocks run with this interpreter and the `dynid` module maturin installed. A block that cannot run here (it
needs the user's robot, a peer's build or hours) says so on the line before its fence, as
`<!-- not run: why -->`; the reason is required.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DOCS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
RUN = {"sh", "python"}
SKIP = re.compile(r"^<!--\s*not run:\s*(.*?)\s*-->$")
# Top-level entries a block must not see or write through (build output, the environment, git).
PRIVATE = {"target", "out", ".git", ".venv"}


@dataclass
class Block:
    path: Path
    line: int  # 1-based line of the opening fence
    lang: str
    code: str
    skip: str | None  # the reason given in `<!-- not run: ... -->`, if any

    @property
    def name(self) -> str:
        return f"{self.path.relative_to(REPO)}:{self.line}"


def blocks(path: Path) -> list[Block]:
    """The fenced blocks of one Markdown file, with the `not run` marker before each."""
    out, lines = [], path.read_text().splitlines()
    i = 0
    while i < len(lines):
        fence = re.match(r"^(```+)\s*([\w-]*)", lines[i])
        if not fence:
            i += 1
            continue
        start, ticks, lang = i, fence.group(1), fence.group(2)
        j = i + 1
        while j < len(lines) and not lines[j].startswith(ticks):
            j += 1
        prev = next((lines[k].strip() for k in range(start - 1, -1, -1) if lines[k].strip()), "")
        marker = SKIP.match(prev)
        out.append(Block(path, start + 1, lang, "\n".join(lines[start + 1 : j]) + "\n", marker and marker.group(1)))
        i = j + 1
    return out


ALL = [b for p in DOCS for b in blocks(p)]
RUNNABLE = [b for b in ALL if b.lang in RUN]

# `dynid` and `cargo run --release [--] ARGS` are the CLI under test; any other cargo call is refused.
SH_PRELUDE = r"""
dynid() { "$DYNID" "$@"; }
cargo() {
  if [[ "${1:-} ${2:-}" == "run --release" ]]; then
    shift 2; [[ "${1:-}" == "--" ]] && shift
    [[ $# -eq 0 ]] && set -- paper --out out/paper
    "$DYNID" "$@"
  else
    echo "doc block: only \`cargo run --release\` runs here; mark the block <!-- not run: ... -->" >&2
    return 2
  fi
}
"""


def scratch(tmp_path: Path, cli: str) -> Path:
    """A directory that looks like the repository (its files linked in) with its own out/ and a
    target/release/dynid that is the CLI under test."""
    for entry in REPO.iterdir():
        if entry.name not in PRIVATE:
            (tmp_path / entry.name).symlink_to(entry)
    (tmp_path / "target" / "release").mkdir(parents=True)
    (tmp_path / "target" / "release" / "dynid").symlink_to(cli)
    return tmp_path


def test_every_skip_says_why():
    """A `not run` marker without a reason would let any block escape the check."""
    for b in ALL:
        assert b.skip is None or b.skip.strip(), f"{b.name}: `<!-- not run: -->` needs a reason"
    assert RUNNABLE, "no sh/python block found — the collector is broken"


def test_readme_first_screen_runs_a_urdf_to_a_model():
    """The README's first screen (first 60 lines) takes a newcomer from a URDF to an identified model
    with three dynid commands, in a block this test runs."""
    readme = [b for b in RUNNABLE if b.path.name == "README.md" and b.line <= 60 and b.skip is None]
    cmds = [line.split()[1] for b in readme for line in b.code.splitlines() if line.startswith("dynid ")]
    assert cmds[:3] == ["excite", "simulate", "identify"], cmds
    assert any(".urdf" in b.code and "identified.urdf" in b.code for b in readme)


PAGES = sorted({b.path for b in RUNNABLE if b.skip is None})


def run_block(block: Block, cwd: Path, cli: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "DYNID": cli, "PYTHONPATH": str(cwd)}
    if block.lang == "sh":
        cmd = ["bash", "-c", "set -euo pipefail\n" + SH_PRELUDE + block.code]
    else:
        cmd = [sys.executable, "-c", block.code]
    return subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=900)


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_page_blocks_run(page: Path, tmp_path: Path, dynid_cli: str):
    cli = str(Path(dynid_cli).resolve())
    cwd = scratch(tmp_path, cli)
    for block in (b for b in RUNNABLE if b.path == page and b.skip is None):
        r = run_block(block, cwd, cli)
        assert r.returncode == 0, f"{block.name} failed ({r.returncode}):\n{r.stderr[-3000:]}\n{r.stdout[-2000:]}"


def test_the_collector_sees_markers(tmp_path: Path):
    """The marker binds to the next fence only, and a reasonless marker is caught."""
    md = tmp_path / "x.md"
    md.write_text(
        "<!-- not run: needs a robot -->\n\n```sh\nfalse\n```\n```python\nx = 1\n```\n<!-- not run: -->\n```sh\n```\n"
    )
    got = blocks(md)
    assert [(b.lang, b.skip) for b in got] == [("sh", "needs a robot"), ("python", None), ("sh", "")]
    assert got[1].code == "x = 1\n"
