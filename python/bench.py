"""Benchmark of the Python bindings (issue 20): ``Arm("puma560").base_regressor(Q, DQ, DDQ)`` with N = 100,000 samples
in one call, against

- the Rust lane-batched throughput: ``examples/batch_throughput.rs`` runs the bindings' own batch driver
  (``src/batch.rs``) from Rust on the same jobs — N samples into a new output (``fresh``), into a preallocated one
  (``reuse``, the Python call with ``out=``) — and the lane-batched kernels alone with their output kept in the
  cache (``kernel``, what ``dynid bench``'s lanes column measures). The plain Python call (``plain``) gets its
  output from the bindings' buffer pool (``src/pool.rs``: the buffer of the previous, dropped output of that size);
  ``new size`` is the plain call on a size never seen (fresh pages, like Rust's ``fresh``);
- a Python loop over Pinocchio's ``computeJointTorqueRegressor`` on the same states (the first ``--pin-samples``).

All measured in this one run, interleaved (Python, Rust, Python, Rust, ...), medians over the rounds, single-threaded
(``threads=1``) and on all cores (the default).

    .venv/bin/python python/bench.py            # after scripts/test.sh (or maturin develop --profile python)
    .venv/bin/python python/bench.py --json out/bench_python.json

Not a timed test: numbers depend on the machine and its load; the README quotes one run.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import dynid
import numpy as np

REPO = Path(__file__).resolve().parents[1]


def rust_example() -> Path:
    """Builds (if needed) and returns the Rust side's binary."""
    # The profile the extension is built with (scripts/test.sh), so both sides run the same machine code.
    cmd = ["cargo", "build", "--profile", "python", "-p", "dynid-python", "--example", "batch_throughput"]
    cmd += ["--message-format=json"]
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(f"error: `{' '.join(cmd[:-1])}` failed:\n{proc.stderr}")
    for line in proc.stdout.splitlines():
        msg = json.loads(line)
        if msg.get("reason") == "compiler-artifact" and msg["target"]["name"] == "batch_throughput":
            return Path(msg["executable"])
    sys.exit("error: cargo did not report the batch_throughput executable")


def time_python(
    arm: dynid.Arm, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, threads: int | None, out: np.ndarray | None
) -> float:
    """ns per sample of one call (input checks and, without ``out``, the output's allocation included)."""
    t0 = time.perf_counter()
    y = arm.base_regressor(q, dq, ddq, threads=threads, out=out)
    dt = time.perf_counter() - t0
    assert y.shape == (len(q), arm.dof, arm.nb)
    return dt * 1e9 / len(q)


def time_rust(exe: Path, samples: int, threads: int, mode: str) -> float:
    args = [str(exe), "puma560", "base_regressor", str(samples), "3", str(threads), mode]
    out = subprocess.run(args, check=True, capture_output=True, text=True).stdout
    return json.loads(out)["median_ns_per_sample"]


def time_pinocchio(arm: dynid.Arm, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> float:
    """ns per sample of a Python loop over pin.computeJointTorqueRegressor (configurations converted beforehand:
    the exported URDF's joints are continuous, so Pinocchio takes (cos, sin) per joint)."""
    import pinocchio as pin

    model = pin.buildModelFromXML(arm.to_urdf())
    data = model.createData()
    qs = [np.ravel(np.column_stack([np.cos(x), np.sin(x)])) if model.nq == 2 * arm.dof else x for x in q]
    t0 = time.perf_counter()
    for k in range(len(q)):
        pin.computeJointTorqueRegressor(model, data, qs[k], dq[k], ddq[k])
    return (time.perf_counter() - t0) * 1e9 / len(q)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=100_000)
    ap.add_argument("--rounds", type=int, default=7, help="interleaved rounds (medians over them)")
    ap.add_argument("--pin-samples", type=int, default=5000, help="states of the Pinocchio loop")
    ap.add_argument("--json", help="also write the numbers here")
    args = ap.parse_args()

    arm = dynid.Arm("puma560")
    rng = np.random.default_rng(42)
    n, N = arm.dof, args.samples
    q = rng.uniform(-np.pi, np.pi, (N, n))
    dq = rng.uniform(-2.0, 2.0, (N, n))
    ddq = rng.uniform(-5.0, 5.0, (N, n))
    exe = rust_example()
    cores = os.cpu_count() or 1

    y = np.zeros((N, n, arm.nb))
    y[:] = 1.0  # touched: `reuse` measures the kernels and the writes, not first-touch page faults
    threads = {"1 thread": (1, 1), f"all cores ({cores})": (None, 0)}
    jobs = [(t, mode) for t in threads for mode in ("new size", "plain", "reuse")]
    rust_mode = {"new size": "fresh", "plain": "fresh", "reuse": "reuse"}
    unseen = iter(range(N - 1, 0, -1))  # a size no earlier call had: the pool cannot serve it
    py: dict[tuple[str, str], list[float]] = {j: [] for j in jobs}
    rs: dict[tuple[str, str], list[float]] = {j: [] for j in jobs}
    kernel_only: list[float] = []
    time_python(arm, q, dq, ddq, 1, None)  # warm-up (CPU clock, allocator)
    for _ in range(args.rounds):
        for label, mode in jobs:
            py_threads, rust_threads = threads[label]
            m = next(unseen) if mode == "new size" else N
            py[(label, mode)].append(
                time_python(arm, q[:m], dq[:m], ddq[:m], py_threads, y if mode == "reuse" else None)
            )
            rs[(label, mode)].append(time_rust(exe, N, rust_threads, rust_mode[mode]))
        kernel_only.append(time_rust(exe, N, 1, "kernel"))
    pin_ns = statistics.median(time_pinocchio(arm, q[: args.pin_samples], dq, ddq) for _ in range(3))
    kernel_ns = statistics.median(kernel_only)

    result: dict = {
        "samples": N,
        "rounds": args.rounds,
        "cpu_count": cores,
        "pinocchio_loop_ns_per_sample": pin_ns,
        "rust_kernel_only_1_thread_ns_per_sample": kernel_ns,
        "jobs": [],
    }
    print(f"PUMA 560 base regressor, N = {N:,} samples in one call; ns per sample, medians of {args.rounds} rounds")
    print(f"Python loop over pin.computeJointTorqueRegressor ({args.pin_samples} states): {pin_ns:,.0f} ns/sample")
    print(f"Rust lane-batched kernels alone, output in cache, 1 thread: {kernel_ns:.1f} ns/sample")
    head = ("", "output", "Python", "Rust", "Rust/Python", "kernels alone/Python", "Pinocchio loop/Python")
    print("{:>14} {:>8} {:>8} {:>8} {:>12} {:>21} {:>22}".format(*head))
    for label, mode in jobs:
        p, r = statistics.median(py[(label, mode)]), statistics.median(rs[(label, mode)])
        result["jobs"].append(
            {
                "threads": label,
                "output": mode,
                "python_ns_per_sample": p,
                "rust_ns_per_sample": r,
                "throughput_vs_rust_same_job": r / p,
                "throughput_vs_rust_kernels_alone": kernel_ns / p,
                "speedup_vs_pinocchio_loop": pin_ns / p,
                "python_runs": py[(label, mode)],
                "rust_runs": rs[(label, mode)],
            }
        )
        print(f"{label:>14} {mode:>8} {p:8.1f} {r:8.1f} {r / p:11.2f}x {kernel_ns / p:20.2f}x {pin_ns / p:21.1f}x")
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
