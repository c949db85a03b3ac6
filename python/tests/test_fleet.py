"""examples/fleet_dask.py on a local Dask cluster (2 worker processes, so every Arm and IdentifyResult crosses a
process boundary pickled): 8 simulated robots, one task each, gathered into one table that equals identifying the
same logs one by one in this process."""

from __future__ import annotations

import json
import subprocess
import sys

import dynid
import pandas as pd
from conftest import REPO

sys.path.insert(0, str(REPO / "examples"))
import fleet_dask  # noqa: E402

ROBOTS = 8


def test_fleet_example_on_a_local_cluster(tmp_path):
    table_csv = tmp_path / "table.csv"
    cmd = [sys.executable, str(REPO / "examples" / "fleet_dask.py"), "--demo", str(ROBOTS), "--dir", str(tmp_path)]
    proc = subprocess.run(cmd + ["--out", str(table_csv)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    table = pd.read_csv(table_csv, index_col="robot", float_precision="round_trip")
    fleet = json.loads((tmp_path / "fleet.json").read_text())
    assert len(fleet) == ROBOTS and list(table.index) == [r["robot"] for r in fleet]
    for r in fleet:
        # The same numbers as identifying the robot here, without Dask: exactly (the table is written with 17
        # significant digits, and pickling moves f64s unchanged).
        here = pd.Series(fleet_dask.row(r["robot"], dynid.identify(r["arm"], r["data"], validate=r["validate"])))
        got = table.loc[r["robot"]]
        for key, value in here.items():
            if key in ("robot",):
                continue
            assert got[key] == value, f"{r['robot']} {key}"
        # Each robot's own friction is found: viscous on both joints within 5 % (1 % torque noise in the log).
        assert set(got["effects_found"].split(",")) == {"viscous1", "viscous2"}, r["robot"]
        for j, truth in enumerate(r["truth"]["viscous"]):
            assert abs(got[f"viscous{j + 1}"] - truth) < 0.05 * truth, (r["robot"], j)
