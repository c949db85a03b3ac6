"""End-to-end identification wall time: issue 22's three cases, medians of interleaved runs.

    python3 scripts/bench_identify.py                      # target/release/dynid, 3 rounds
    python3 scripts/bench_identify.py --dynid OLD --dynid target/release/dynid --rounds 5
    python3 scripts/bench_identify.py --cases six_dof,dfki_loo --markdown docs/bench_identify.md

Cases (data made once with `dynid simulate` into target/bench-identify/, reused afterwards):
- six_dof: PUMA 560 with viscous friction its table lacks, three 34 s runs at 100 Hz with ~4.6 %
  of the samples dropped (uneven steps) for training and a fourth for validation (~13,200
  samples in all), `identify --effects auto --validate`.
- dfki_loo: the real DFKI double pendulum (data/real), leave-one-run-out over its 8 runs.
- puma_1e6: the README's 1,000,000-sample PUMA 560 log (250 MB of CSV; simulating it takes
  about a minute the first time), `identify` on it alone.

Each round runs every case with every binary in turn (interleaved: this 2-core VM's speed swings
2x from minute to minute, so ratios from one run are what to read). Per case and binary: median
and min wall time, peak RSS, and whether the results equal the first binary's (every report.json
field but the command line, numbers to 1e-6 relative).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "target" / "bench-identify"
DFKI = ROOT / "data" / "real" / "dfki_double_pendulum"
DFKI_RUNS = ["00", "01", "02", "04", "05", "11", "12", "13"]
VISCOUS = ROOT / "docs" / "examples" / "puma560_viscous.params.toml"

# Four sine trajectories of the six-joint case (rad, rad/s): fixed, so every machine fits the same data.
SIX_DOF_TRAJ = [
    ([1.2, 0.9, 1.1, 1.4, 1.0, 1.3], [0.61, 1.07, 1.43, 1.91, 2.29, 2.71]),
    ([1.0, 1.1, 0.9, 1.5, 1.2, 0.9], [0.73, 0.97, 1.61, 1.83, 2.41, 2.57]),
    ([1.4, 0.8, 1.2, 1.1, 1.4, 1.1], [0.53, 1.19, 1.37, 2.03, 2.17, 2.83]),
    ([1.1, 1.0, 1.0, 1.3, 0.9, 1.5], [0.67, 1.13, 1.51, 1.77, 2.33, 2.63]),
]


def run(cmd: list[str], **kw) -> None:
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        sys.exit(f"bench_identify: `{' '.join(cmd)}` failed ({r.returncode}):\n{r.stderr[-2000:]}")


def atomic_write(path: Path, text: str) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(text)
    tmp.replace(path)


def make_six_dof(dynid: str) -> list[Path]:
    """Simulates the four runs (once) and drops samples in an irregular, fixed pattern."""
    out = []
    for i, (amp, omega) in enumerate(SIX_DOF_TRAJ, start=1):
        path = DATA / f"six_dof_{i}.csv"
        out.append(path)
        if path.exists():
            continue
        traj = DATA / f"six_dof_{i}.json"
        spec = {"kind": "sine", "amplitude": amp, "omega": omega, "duration": 34.0}
        spec["offset"] = [0, 0.3, -0.2, 0, 0, 0]
        atomic_write(traj, json.dumps(spec))
        full = DATA / f"six_dof_{i}.full.csv"
        run(
            [dynid, "simulate", "--arm", "puma560", "--params", str(VISCOUS), "--trajectory", str(traj)]
            + ["--controller", "ctc", "--dt", "0.0002", "--log-every", "50", "--tau-noise", "0.01"]
            + ["--encoder-counts", "1048576", "--positions-only", "--seed", str(i), "--out", str(full)]
        )
        lines = full.read_text().splitlines()
        kept = [lines[0]] + [ln for k, ln in enumerate(lines[1:]) if k % 37 != 5 and k % 53 != 11]
        atomic_write(path, "\n".join(kept) + "\n")
        full.unlink()
    return out


def make_puma_1e6(dynid: str) -> Path:
    path = DATA / "puma1e6.csv"
    if not path.exists():
        print("[bench_identify] simulating the 1e6-sample PUMA log (once, ~1 min) ...", file=sys.stderr)
        tmp = DATA / "puma1e6.partial.csv"
        run(
            [dynid, "simulate", "--arm", "puma560", "--params", str(VISCOUS)]
            + ["--trajectory", str(ROOT / "docs" / "examples" / "puma560_sine_1000s.json")]
            + ["--controller", "ctc", "--dt", "0.0002", "--log-every", "5", "--tau-noise", "0.01"]
            + ["--encoder-counts", "1048576", "--positions-only", "--out", str(tmp)]
        )
        tmp.replace(path)
    return path


def case_args(name: str, dynid: str) -> list[str]:
    if name == "six_dof":
        runs = make_six_dof(dynid)
        args = ["--arm", "puma560", "--effects", "auto"]
        for r in runs[:3]:
            args += ["--data", str(r)]
        return args + ["--validate", str(runs[3])]
    if name == "dfki_loo":
        args = ["--arm", str(DFKI / "arm.toml"), "--leave-one-out"]
        for r in DFKI_RUNS:
            args += ["--data", str(DFKI / f"run_{r}.csv.gz")]
        return args
    if name == "puma_1e6":
        return ["--arm", "puma560", "--data", str(make_puma_1e6(dynid))]
    sys.exit(f"bench_identify: unknown case `{name}` (six_dof, dfki_loo, puma_1e6)")


def timed(cmd: list[str]) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB) of one run."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode() if proc.stderr else ""
    if os.waitstatus_to_exitcode(status) != 0:
        sys.exit(f"bench_identify: `{' '.join(cmd)}` failed:\n{err[-2000:]}")
    return wall, usage.ru_maxrss / 1024.0


def comparable(report: Path) -> object:
    """report.json without its command line (which names the output folder)."""
    d = json.loads(report.read_text())
    d.pop("command", None)
    return d


def close(a: object, b: object, solver: bool = False) -> bool:
    """Equal, numbers to 1e-6 relative (the scan's held-out errors move in the 9th digit). In the
    `physical` block (`solver`): to 1e-4 relative or 1e-7 absolute, its Newton step count not
    compared. That block is an interior-point solution stopped at a duality gap of 1e-10 of its
    objective, which fixes a parameter in a direction the data barely curve only to about the
    square root of that: a kernel's rounding (generator 0.1.5's fused multiply-adds, 1e-12 in the
    fit) moved a 0.8 mm centre-of-mass coordinate by 8e-5 relative and the step count 77 -> 74."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(
            close(a[k], b[k], solver or k == "physical") for k in a if not (solver and k == "newton_steps")
        )
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(close(x, y, solver) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float):
        d = abs(a - b)
        if solver:
            return d <= 1e-4 * max(abs(a), abs(b)) or d <= 1e-7
        return d <= 1e-6 * max(abs(a), abs(b), 1e-300)
    return a == b


def reports(out: Path) -> list:
    return [comparable(p) for p in sorted(out.rglob("report.json"))]


def shown(b: str) -> str:
    """A binary's path, relative to the repository when inside it (no machine paths in tables)."""
    p = Path(b).resolve()
    return str(p.relative_to(ROOT)) if p.is_relative_to(ROOT) else p.name


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dynid", action="append", help="binary to time (repeat to compare; default target/release/dynid)")
    ap.add_argument("--cases", default="six_dof,dfki_loo,puma_1e6")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--markdown", type=Path, help="write the table here too")
    a = ap.parse_args()
    bins = a.dynid or [str(ROOT / "target" / "release" / "dynid")]
    for b in bins:
        if not Path(b).is_file():
            sys.exit(f"bench_identify: {b} not found — `cargo build --release` first, or pass --dynid PATH")
    DATA.mkdir(parents=True, exist_ok=True)
    cases = [c.strip() for c in a.cases.split(",") if c.strip()]
    args = {c: case_args(c, bins[-1]) for c in cases}
    load = open("/proc/loadavg").read().split()[:3] if Path("/proc/loadavg").exists() else ["?"]
    times: dict[tuple[str, str], list[float]] = {}
    rss: dict[tuple[str, str], float] = {}
    same: dict[tuple[str, str], bool] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for rnd in range(a.rounds):
            for c in cases:
                first = None
                for b in bins:
                    out = Path(tmp) / f"{c}-{rnd}-{bins.index(b)}"
                    wall, mb = timed([b, "identify", *args[c], "--out", str(out)])
                    times.setdefault((c, b), []).append(wall)
                    rss[(c, b)] = max(rss.get((c, b), 0.0), mb)
                    got = reports(out)
                    first = got if first is None else first
                    same[(c, b)] = same.get((c, b), True) and bool(got) and close(got, first)
                    print(f"[bench_identify] round {rnd + 1} {c} {b}: {wall:.2f} s, {mb:.0f} MB", file=sys.stderr)
    lines = [
        f"Load average at the start: {' '.join(load)}; {os.cpu_count()} CPUs; {a.rounds} interleaved rounds.",
        "",
        "| case | binary | median (s) | min (s) | peak RSS (MB) | results equal the first binary's |",
        "|---|---|---|---|---|---|",
    ]
    for c in cases:
        for b in bins:
            t = times[(c, b)]
            eq = "yes" if same[(c, b)] else "NO"
            lines.append(
                f"| {c} | `{shown(b)}` | {statistics.median(t):.2f} | {min(t):.2f} | {rss[(c, b)]:.0f} | {eq} |"
            )
    text = "\n".join(lines) + "\n"
    print(text)
    if a.markdown:
        atomic_write(a.markdown, text)
    return 0 if all(same.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
