"""Eight lanes against four: the throughput gained per sample by the AVX-512 lane forms, over rounds.

    python3 scripts/bench_lanes.py                      # target/release/dynid, 7 rounds
    python3 scripts/bench_lanes.py --dynid BIN --rounds 5 --markdown docs/bench_lanes.md

`dynid bench` times each kernel's four- and eight-lane forms one after the other in one run, and on
this VM a single run's ratio swings by ±30 %; so this runs `dynid bench --arm <arm>` once per arm
per round and reports, per kernel, the median ns per sample of each form and the median (range) of
the per-round ratios four-lane / eight-lane: for the forms that write every output, and for the
forms that leave the constant-zero outputs to the caller's buffer (`call_lanes_skip_zeros`,
`call_lanes8_skip_zeros`). Bar (issue 22): ≥ 1.6× on a machine with AVX-512.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ARMS = ["panda", "planar2", "puma560", "scara"]
# `dynid bench`'s table line: arm, kernel, one call, lanes, 8 lanes, "r× (s×)", reference, ratio.
LINE = re.compile(r"^(\w+)\s+(\w+)\s+[\d.]+\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)× \(([\d.]+)×\)")


def one_run(dynid: str, arm: str) -> list[tuple[str, str, float, float, float, float]]:
    out = subprocess.run(
        [dynid, "bench", "--arm", arm, "--samples", "1000"], capture_output=True, text=True, check=True
    ).stdout
    rows = []
    for line in out.splitlines():
        if m := LINE.match(line):
            rows.append((m[1], m[2], float(m[3]), float(m[4]), float(m[5]), float(m[6])))
    if not rows:
        sys.exit(f"bench_lanes: no kernel lines in `{dynid} bench --arm {arm}` (is it a dynid with lane forms?)")
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dynid", default=str(ROOT / "target/release/dynid"))
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--markdown", type=Path, help="also write the table here (temp file, then rename)")
    args = ap.parse_args()
    if not Path(args.dynid).is_file():
        sys.exit(f"bench_lanes: {args.dynid} not found — build it: cargo build --release")
    load = lambda: " ".join(Path("/proc/loadavg").read_text().split()[:3]) if Path("/proc/loadavg").exists() else "?"  # noqa: E731
    before = load()
    runs: dict[tuple[str, str], list[tuple[float, float, float, float]]] = {}
    for r in range(args.rounds):
        print(f"[bench_lanes] round {r + 1}/{args.rounds} ...", file=sys.stderr)
        for arm in ARMS:
            for a, k, lanes, lanes8, dense, skip in one_run(args.dynid, arm):
                runs.setdefault((a, k), []).append((lanes, lanes8, dense, skip))
    med = statistics.median
    lines = [
        "## Eight lanes against four",
        "",
        "`python3 scripts/bench_lanes.py` (the kernels' four- and eight-lane forms, see `dynid::pack`).",
        "",
        f"{args.rounds} rounds of `dynid bench --arm <arm>` (every arm once per round); load average {before} before,"
        f" {load()} after; {os.cpu_count()} CPUs. ns per sample, medians; ratios: median [range] of the per-round"
        " four-lane / eight-lane throughput, all outputs written and constant zeros skipped. Bar: ≥ 1.6×.",
        "",
        "| arm | kernel | lanes (ns/sample) | 8 lanes (ns/sample) | lanes / 8 lanes | zeros skipped |",
        "|---|---|---:|---:|---:|---:|",
    ]
    for (arm, k), v in sorted(runs.items()):
        d, s = [x[2] for x in v], [x[3] for x in v]
        lines.append(
            f"| {arm} | {k} | {med(x[0] for x in v):.1f} | {med(x[1] for x in v):.1f} "
            f"| {med(d):.2f}× [{min(d):.2f}–{max(d):.2f}] | {med(s):.2f}× [{min(s):.2f}–{max(s):.2f}] |"
        )
    dense_ok = sum(med(x[2] for x in v) >= 1.6 for v in runs.values())
    skip_ok = sum(med(x[3] for x in v) >= 1.6 for v in runs.values())
    n = len(runs)
    lines += ["", f"{dense_ok} of {n} kernels ≥ 1.6× writing every output, {skip_ok} of {n} skipping zeros."]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.markdown:
        tmp = args.markdown.with_suffix(args.markdown.suffix + ".tmp")
        tmp.write_text(text)
        tmp.replace(args.markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
