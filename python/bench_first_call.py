"""A fresh process's first call (issue 37): ``Arm("puma560").base_regressor(Q, DQ, DDQ)`` on N = 100,000 random
states, timed as a user's script meets it — the first kernel call after ``import dynid``, then the second on the same
inputs — against a Python loop over Pinocchio's ``computeJointTorqueRegressor`` (the first ``--pin-samples``
states, as in ``python/bench.py``). Each round is a new interpreter, so nothing is warm but the page cache.

    .venv/bin/python python/bench_first_call.py              # 5 rounds, medians
    .venv/bin/python python/bench_first_call.py --rounds 9

Not a timed test: numbers depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys

ONE_ROUND = r"""
import json, sys, time
import numpy as np
import dynid

n_samples, threads = int(sys.argv[1]), (None if sys.argv[2] == "all" else int(sys.argv[2]))
arm = dynid.Arm("puma560")
rng = np.random.default_rng(42)
q = rng.uniform(-np.pi, np.pi, (n_samples, arm.dof))
dq = rng.uniform(-2.0, 2.0, (n_samples, arm.dof))
ddq = rng.uniform(-5.0, 5.0, (n_samples, arm.dof))
ns = []
for _ in range(2):
    t0 = time.perf_counter()
    y = arm.base_regressor(q, dq, ddq, threads=threads)
    ns.append((time.perf_counter() - t0) * 1e9 / n_samples)
    del y
print(json.dumps({"first": ns[0], "second": ns[1]}))
"""

PIN = r"""
import json, sys, time
import numpy as np
import dynid
import pinocchio as pin

k = int(sys.argv[1])
arm = dynid.Arm("puma560")
rng = np.random.default_rng(42)
q = rng.uniform(-np.pi, np.pi, (k, arm.dof))
dq = rng.uniform(-2.0, 2.0, (k, arm.dof))
ddq = rng.uniform(-5.0, 5.0, (k, arm.dof))
model = pin.buildModelFromXML(arm.to_urdf())
data = model.createData()
qs = [np.ravel(np.column_stack([np.cos(x), np.sin(x)])) if model.nq == 2 * arm.dof else x for x in q]
t0 = time.perf_counter()
for i in range(k):
    pin.computeJointTorqueRegressor(model, data, qs[i], dq[i], ddq[i])
print(json.dumps({"pin": (time.perf_counter() - t0) * 1e9 / k}))
"""


def run(code: str, *args: object) -> dict:
    out = subprocess.run([sys.executable, "-c", code, *map(str, args)], check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=100_000)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--pin-samples", type=int, default=5000)
    ap.add_argument("--json", help="also write the numbers here")
    args = ap.parse_args()
    rows: dict[str, dict[str, list[float]]] = {}
    pin = []
    for _ in range(args.rounds):  # interleaved: each configuration and Pinocchio once per round
        for label, threads in (("1 thread", 1), ("all cores", "all")):
            r = run(ONE_ROUND, args.samples, threads)
            for k, v in r.items():
                rows.setdefault(label, {}).setdefault(k, []).append(v)
        pin.append(run(PIN, args.pin_samples)["pin"])
    pin_ns = statistics.median(pin)
    print(
        f"PUMA 560 base regressor, N = {args.samples:,}, a new interpreter per round, medians of {args.rounds} rounds"
    )
    print(f"Python loop over pin.computeJointTorqueRegressor: {pin_ns:,.0f} ns/sample")
    print(f"{'':>10} {'call':>7} {'ns/sample':>10} {'Pinocchio loop / dynid':>23}")
    result = {"samples": args.samples, "rounds": args.rounds, "pinocchio_loop_ns_per_sample": pin_ns, "jobs": []}
    for label, r in rows.items():
        for call in ("first", "second"):
            ns = statistics.median(r[call])
            print(f"{label:>10} {call:>7} {ns:10.1f} {pin_ns / ns:22.1f}x")
            result["jobs"].append({"threads": label, "call": call, "ns_per_sample": ns, "runs": r[call]})
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
