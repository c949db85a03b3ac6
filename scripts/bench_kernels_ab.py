"""Two or more `dynid` binaries' kernels, side by side, in interleaved rounds of fresh copies.

    python3 scripts/bench_kernels_ab.py --dynid OLD --dynid target/release/dynid
    python3 scripts/bench_kernels_ab.py --dynid OLD --dynid NEW --arms puma560,panda --rounds 7

What a kernel change is judged by. On this VM a kernel's time moves with more than its code: the
machine's speed swings up to 2x from minute to minute, and where the program's file sits in
memory moves a large kernel by up to 1.6x (two byte-identical copies of one binary, side by
side: PUMA 560 regressor 157 and 251 ns, each copy the same every time). So every round copies
each binary to a new file and runs `dynid bench --json --arm <arm>` with each in turn (order
alternating between rounds); the table gives per kernel each binary's median ns per call (one
call, `dynid bench`'s protocol) and the median of the per-round ratios of the first binary's
time to each other's (above 1: faster than the first).
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def kernel_times(dynid: Path, arm: str) -> dict[str, float]:
    """`dynid bench --json --arm <arm>`: ns per call of each generated kernel (also used by
    bench_sympybotics.py)."""
    r = subprocess.run(
        [str(dynid), "bench", "--json", "--arm", arm, "--samples", "1000"], capture_output=True, text=True
    )
    if r.returncode != 0:
        sys.exit(f"`{dynid} bench --arm {arm}` failed ({r.returncode}):\n{r.stderr[-2000:]}")
    out = json.loads(r.stdout)
    return {k["kernel"]: k["generated_ns"] for k in out["kernels"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dynid", action="append", required=True, help="a binary (two or more; the first is the base)")
    ap.add_argument("--arms", default="planar2,puma560,panda")
    ap.add_argument("--rounds", type=int, default=5)
    a = ap.parse_args()
    if len(a.dynid) < 2:
        ap.error("give at least two --dynid binaries")
    if a.rounds < 1:
        ap.error("--rounds must be at least 1")
    for b in a.dynid:
        if not Path(b).is_file():
            sys.exit(f"bench_kernels_ab: {b} not found")
    arms = [x for x in a.arms.split(",") if x]
    # times[binary index][(arm, kernel)] = [ns per call, one per round]
    times: list[dict[tuple[str, str], list[float]]] = [{} for _ in a.dynid]
    for r in range(a.rounds):
        print(f"[bench_kernels_ab] round {r + 1}/{a.rounds} ...", file=sys.stderr)
        order = list(range(len(a.dynid)))
        if r % 2:
            order.reverse()
        with tempfile.TemporaryDirectory(prefix="bench-kernels-ab-") as tmp:
            for i in order:
                copy = Path(tmp) / f"dynid-{i}"
                shutil.copy2(a.dynid[i], copy)
                for arm in arms:
                    for kernel, t in kernel_times(copy, arm).items():
                        times[i].setdefault((arm, kernel), []).append(t)
    names = [Path(b).name for b in a.dynid]
    head = "| arm | kernel | " + " | ".join(f"{n} (ns)" for n in names)
    head += " | " + " | ".join(f"{names[0]} / {n}" for n in names[1:]) + " |"
    print(f"{a.rounds} interleaved rounds, every binary a fresh copy each round; medians.\n")
    print(head)
    print("|---|---|" + "---:|" * (2 * len(names) - 1))
    for key in sorted(times[0]):
        cells = []
        for t in times:
            cells.append(f"{statistics.median(t[key]):.1f}")
        ratios = []
        for t in times[1:]:
            per_round = [b / x for b, x in zip(times[0][key], t[key])]
            ratios.append(f"{statistics.median(per_round):.2f}× [{min(per_round):.2f}–{max(per_round):.2f}]")
        print(f"| {key[0]} | {key[1]} | " + " | ".join(cells) + " | " + " | ".join(ratios) + " |")


if __name__ == "__main__":
    main()
