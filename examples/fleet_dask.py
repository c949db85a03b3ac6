"""Identify a fleet of robots in parallel with Dask: one task per robot, the results gathered into one table.

A fleet is a JSON list of robots, each ``{"robot": ID, "arm": NAME_OR_DH_TOML, "data": [LOG, ...], "validate": LOG}``
(``validate`` optional; logs are the CSV / .csv.gz / .mcap files ``dynid identify`` reads). Each task receives the
robot's ``dynid.Arm`` (pickled to the worker) and the log paths, runs ``dynid.identify`` there (the GIL is released
while it runs) and sends back the ``IdentifyResult`` (pickled); the client turns the results into one pandas table:
a row per robot with the effects found, the errors before/after and every base parameter with its %σ.

    python examples/fleet_dask.py --demo 8 --dir out/fleet             # make 8 simulated robots' logs, then run
    python examples/fleet_dask.py fleet.json --out table.csv             # a local cluster on this machine
    python examples/fleet_dask.py fleet.json --scheduler tcp://host:8786 # any running Dask cluster

The logs must be readable at the same path on every worker (a shared file system, or ship the data as arrays:
``dynid.identify`` also takes DataFrames).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import dynid
import numpy as np
import pandas as pd


def identify_robot(robot: str, arm: dynid.Arm, data: list[str], validate: str | None) -> dynid.IdentifyResult:
    """One task: runs on a worker."""
    return dynid.identify(arm, data, validate=validate)


def row(robot: str, result: dynid.IdentifyResult) -> dict[str, Any]:
    """One robot's line of the fleet table."""
    err = result.errors
    out: dict[str, Any] = {
        "robot": robot,
        "arm": result.arm,
        "effects_found": ",".join(e["name"] for e in result.effects_found),
        "train_before_pct": 100 * err["before"]["train"]["overall"],
        "train_after_pct": 100 * err["after"]["train"]["overall"],
    }
    if err["after"]["validation"] is not None:
        out["validation_before_pct"] = 100 * err["before"]["validation"]["overall"]
        out["validation_after_pct"] = 100 * err["after"]["validation"]["overall"]
    for p in result.parameters + result.effects:
        out[p["name"]] = p["value"]
        out[f"{p['name']}_rel_std_pct"] = p["rel_std_percent"]
    return out


def identify_fleet(fleet: list[dict[str, Any]], client: Any) -> pd.DataFrame:
    """Submits one task per robot to the Dask ``client`` and gathers the results into one table."""
    futures = [
        client.submit(
            identify_robot,
            r["robot"],
            dynid.Arm(str(r["arm"])),
            [str(d) for d in r["data"]],
            r.get("validate"),
            key=f"identify-{r['robot']}",
            pure=False,
        )
        for r in fleet
    ]
    results = client.gather(futures)
    return pd.DataFrame([row(r["robot"], res) for r, res in zip(fleet, results)]).set_index("robot")


def fourier_states(t: np.ndarray, coef: np.ndarray, f0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q = Σ_k a_k sin(k ω t) + b_k cos(k ω t) per joint (coef: joints × harmonics × 2) and its derivatives."""
    w = 2 * np.pi * f0 * np.arange(1, coef.shape[1] + 1)
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    a, b = coef[..., 0], coef[..., 1]
    q = s @ a.T + c @ b.T
    dq = (c * w) @ a.T - (s * w) @ b.T
    ddq = -(s * w**2) @ a.T - (c * w**2) @ b.T
    return q, dq, ddq


def make_demo_fleet(directory: Path, robots: int = 8, seconds: float = 20.0, rate: float = 200.0) -> list[dict]:
    """Simulated logs of ``robots`` planar2 arms, each with its own masses and viscous friction, through dynid's
    own inverse dynamics: ``t, q, tau`` at ``rate`` Hz with 1 % torque noise and a 16-bit encoder."""
    arm = dynid.Arm("planar2")
    directory.mkdir(parents=True, exist_ok=True)
    fleet = []
    for k in range(robots):
        rng = np.random.default_rng(1000 + k)
        m = rng.uniform(1.0, 3.0, 2)
        x = rng.uniform(0.3, 0.6, 2)  # centre of mass along the link
        p = np.zeros(20)
        for j in range(2):  # a slender link: ZZ = m x², MX = m x
            p[10 * j + 5], p[10 * j + 6], p[10 * j + 9] = m[j] * x[j] ** 2 + 0.01, m[j] * x[j], m[j]
        viscous = rng.uniform(0.3, 1.0, 2)
        for name, span, f0 in (("train", seconds, 0.1), ("validate", seconds / 2, 0.15)):
            t = np.arange(0.0, span, 1.0 / rate)
            q, dq, ddq = fourier_states(t, rng.uniform(-0.4, 0.4, (2, 4, 2)), f0)
            tau = arm.inverse_dynamics(q, dq, ddq, p) + viscous * dq
            tau += 0.01 * tau.std(axis=0) * rng.normal(size=tau.shape)
            step = 2 * np.pi / 2**16
            cols = {"t": t, **{f"q{j + 1}": np.round(q[:, j] / step) * step for j in range(2)}}
            cols |= {f"tau{j + 1}": tau[:, j] for j in range(2)}
            pd.DataFrame(cols).to_csv(directory / f"robot{k}_{name}.csv", index=False, float_format="%.17g")
        fleet.append(
            {
                "robot": f"robot{k}",
                "arm": "planar2",
                "data": [str(directory / f"robot{k}_train.csv")],
                "validate": str(directory / f"robot{k}_validate.csv"),
                "truth": {"viscous": viscous.tolist()},
            }
        )
    (directory / "fleet.json").write_text(json.dumps(fleet, indent=1))
    return fleet


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("fleet", nargs="?", help="fleet JSON (see the module docs)")
    ap.add_argument("--demo", type=int, metavar="N", help="make N simulated robots' logs in --dir and use them")
    ap.add_argument("--dir", default="out/fleet", help="where --demo writes its logs (default out/fleet)")
    ap.add_argument("--scheduler", help="address of a running Dask scheduler (default: a local cluster)")
    ap.add_argument("--workers", type=int, default=2, help="local cluster: worker processes (default 2)")
    ap.add_argument("--out", help="write the table as CSV here")
    args = ap.parse_args(argv)
    if args.demo:
        fleet = make_demo_fleet(Path(args.dir), args.demo)
    elif args.fleet:
        fleet = json.loads(Path(args.fleet).read_text())
    else:
        ap.error("give a fleet JSON or --demo N")
    from dask.distributed import Client, LocalCluster

    if args.scheduler:
        client = Client(args.scheduler)
    else:
        cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1, dashboard_address=None)
        client = Client(cluster)
    with client:
        table = identify_fleet(fleet, client)
    pd.set_option("display.width", 200)
    print(table[[c for c in table.columns if not c.endswith("_rel_std_pct")]].to_string(float_format="%.4g"))
    if args.out:
        table.to_csv(args.out, float_format="%.17g")  # every digit: the test compares exactly
    return 0


if __name__ == "__main__":
    sys.exit(main())
