"""The round trip through the user's URDF (issue 39): `dynid identify --arm ROBOT.urdf` writes identified.urdf,
ROBOT.urdf with the identified inertials. The oracle is Pinocchio: its RNEA on identified.urdf must equal
`dynid torque --arm ROBOT.urdf --params identified.params.toml` (rigid part) to 1e-9, the tolerance
tests/pinocchio/check_urdf.py holds the import to (both sides are exact in double precision; 1e-9 leaves room for
the frame changes' rounding and the 17-digit text of the parameters).

The data are Pinocchio's own torques on the original URDF along two multi-sine motions, so the identification has
something real to fit; what is checked is only that the written file carries what was identified."""

from __future__ import annotations

import csv
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO

sys.path.insert(0, str(REPO / "tests" / "pinocchio"))
import check_urdf  # noqa: E402

pin = pytest.importorskip("pinocchio", reason="the round-trip oracle is Pinocchio (scripts/test.sh installs it)")

# UR5: six joints, every link moving. Panda's default chain: the hand and its mimic fingers are lumped into
# link 7, so the rewrite must subtract their CAD inertials from the identified body.
CASES = ["ur5", "panda"]


def motion(n: int, seconds: float, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A multi-sine q(t) per joint (five harmonics of 0.1 Hz, amplitude ≤ ~1 rad) with exact dq, ddq."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 0.01)
    w = 2 * math.pi * 0.1 * np.arange(1, 6)
    a, b = rng.uniform(-0.25, 0.25, (2, n, 5)) / np.arange(1, 6) ** 0.5
    arg = np.outer(t, w)
    q = np.sin(arg) @ a.T + np.cos(arg) @ b.T
    dq = (np.cos(arg) * w) @ a.T - (np.sin(arg) * w) @ b.T
    ddq = -(np.sin(arg) * w**2) @ a.T - (np.cos(arg) * w**2) @ b.T
    return t, q, dq, ddq


def write_run(path: Path, urdf: Path, chain: list[str], seed: int) -> None:
    n = len(chain)
    t, q, dq, ddq = motion(n, 40.0, seed)
    tau = check_urdf.pinocchio_torques(urdf, chain, np.hstack([q, dq, ddq]))
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t"] + [f"{b}{i}" for b in ("q", "dq", "ddq", "tau") for i in range(1, n + 1)])
        for k in range(len(t)):
            w.writerow([repr(float(x)) for x in (t[k], *q[k], *dq[k], *ddq[k], *tau[k])])


def rigid(params: Path, out: Path) -> Path:
    """The params file without its [effects] table: Pinocchio's RNEA has no friction."""
    text = params.read_text()
    out.write_text(text.split("[effects]")[0])
    return out


@pytest.mark.parametrize("label", CASES)
def test_pinocchio_on_identified_urdf_equals_dynid_torque(dynid_cli, tmp_path, label):
    robots = check_urdf.robots_dir(None)
    assert robots, "example-robot-data not installed — run scripts/test.sh"
    case = next(c for c in check_urdf.CASES if c.label == label)
    urdf = robots / case.urdf
    summary = check_urdf.import_case(dynid_cli, robots, case, tmp_path / "imported")
    chain = summary["chain"]
    write_run(tmp_path / "train.csv", urdf, chain, 1)
    write_run(tmp_path / "val.csv", urdf, chain, 2)
    out = tmp_path / "id"
    cmd = [dynid_cli, "identify", "--arm", str(urdf), "--data", str(tmp_path / "train.csv")]
    cmd += ["--validate", str(tmp_path / "val.csv"), "--effects", "viscous,coulomb", "--out", str(out)]
    subprocess.run(cmd, check=True, capture_output=True)
    written = out / "identified.urdf"
    assert written.is_file()
    params = rigid(out / "identified.params.toml", tmp_path / "rigid.params.toml")
    rng = np.random.default_rng(3)
    states = check_urdf.random_states({"joint": [{"kind": "revolute"}] * len(chain)}, 30, rng)
    ours = check_urdf.dynid_torques(dynid_cli, str(urdf), params, states, tmp_path)
    ref = check_urdf.pinocchio_torques(written, chain, states)
    err = check_urdf.max_relative(ours, ref)
    print(f"{label}: max rel {err:.2e}")
    assert err < 1e-9, f"{label}: Pinocchio on identified.urdf vs dynid torque: max rel {err:.2e}"
    # The identified viscous/Coulomb coefficients are the chain joints' <dynamics>.
    model = pin.buildModelFromUrdf(str(written))
    assert any(abs(d) > 0 for d in model.damping) or any(abs(f) > 0 for f in model.friction)

    # Through the TOML import-urdf wrote (its [source] records the URDF): the same identified.urdf.
    toml = tmp_path / "imported" / f"{label}.toml"
    out2 = tmp_path / "id2"
    cmd2 = [dynid_cli, "identify", "--arm", str(toml), "--data", str(tmp_path / "train.csv")]
    cmd2 += ["--validate", str(tmp_path / "val.csv"), "--effects", "viscous,coulomb", "--out", str(out2)]
    subprocess.run(cmd2, check=True, capture_output=True)
    assert (out2 / "identified.urdf").read_text() == written.read_text()
