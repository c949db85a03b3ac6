"""The round trip through the user's URDF (issue 39): `dynid identify --arm ROBOT.urdf` writes identified.urdf,
ROBOT.urdf with the identified inertials. The oracle is Pinocchio: its RNEA on identified.urdf must equal
`dynid torque --arm ROBOT.urdf --params identified.params.toml` (rigid part) to 1e-9, the tolerance
tests/pinocchio/check_urdf.py holds the import to (both sides are exact in double precision; 1e-9 leaves room for
the frame changes' rounding and the 17-digit text of the parameters).

The data are Pinocchio's own torques on the original URDF along two multi-sine motions, so the identification has
something real to fit; what is checked is only that the written file carries what was identified.
`test_every_urdf_round_trips` does so for every URDF the project ships or tests with (data/urdf/, TIAGo, every
example-robot-data import of check_urdf.py) and also compares the XML trees outside the replaced elements."""

from __future__ import annotations

import csv
import math
import subprocess
import sys
import tomllib
import xml.etree.ElementTree as ET
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


def write_run(path: Path, urdf: Path, chain: list[str], seed: int, seconds: float = 40.0, span=None) -> None:  # noqa: ANN001
    """Pinocchio's torques along `motion` (joint j's amplitude scaled by span[j], e.g. metres for a prismatic
    joint) as the CSV identify reads."""
    n = len(chain)
    t, q, dq, ddq = motion(n, seconds, seed)
    if span is not None:
        q, dq, ddq = q * span, dq * span, ddq * span
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


# --- every URDF the project ships or tests with ------------------------------------------------------------------

# (label, URDF, --base, --tip): data/urdf/, the TIAGo of data/real/tiago_figaroh, and every example-robot-data
# import tests/pinocchio/check_urdf.py checks (the robots' own chains, grippers and hands lumped, arms cut out of
# larger trees). Paths of example-robot-data are relative to its robots/ folder.
SHIPPED = [(f"data_{f.stem}", str(f), None, None) for f in sorted((REPO / "data" / "urdf").glob("*.urdf"))]
SHIPPED += [("tiago_figaroh", str(REPO / "data" / "real" / "tiago_figaroh" / "tiago.urdf"), None, None)]
ALL_URDFS = SHIPPED + [(c.label, c.urdf, c.base, c.tip) for c in check_urdf.CASES]


def tree(path: Path, moving_links: set[str], chain: set[str]) -> ET.Element:
    """The URDF's XML tree (comments kept) without the moving links' <inertial> and the chain joints'
    <dynamics>, whitespace-only text dropped."""
    root = ET.parse(path, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))).getroot()
    for el in root:
        drop = {"link": ("inertial", moving_links), "joint": ("dynamics", chain)}.get(el.tag)
        if drop and el.get("name") in drop[1]:
            for child in el.findall(drop[0]):
                el.remove(child)
    for el in root.iter():
        el.text = (el.text or "").strip() or None
        el.tail = (el.tail or "").strip() or None
    return root


def moving_links(robot: ET.Element, first_joint: str) -> set[str]:
    """Every link the chain moves: the subtree below its first joint (the chain links and the bodies fixed or
    locked on them, whose <inertial> the rewrite may zero when the identified body cannot hold their CAD inertials
    — see src/urdf/roundtrip.rs); bodies on the base are not in it."""
    children: dict[str, list[str]] = {}
    top = ""
    for j in robot.findall("joint"):
        parent, child = j.find("parent").get("link"), j.find("child").get("link")
        children.setdefault(parent, []).append(child)
        if j.get("name") == first_joint:
            top = child
    out, stack = set(), [top]
    while stack:
        link = stack.pop()
        out.add(link)
        stack += children.get(link, [])
    return out


def same_tree(a: ET.Element, b: ET.Element, where: str = "") -> str | None:
    """None if equal, else where they first differ."""
    here = f"{where}/{a.tag if isinstance(a.tag, str) else 'comment'}[{a.get('name', '')}]"
    if (a.tag, a.attrib, a.text, a.tail) != (b.tag, b.attrib, b.text, b.tail):
        return f"{here}: {(a.tag, a.attrib, a.text)} != {(b.tag, b.attrib, b.text)}"
    if len(a) != len(b):
        return f"{here}: {len(a)} children != {len(b)}"
    for x, y in zip(a, b):
        if diff := same_tree(x, y, here):
            return diff
    return None


@pytest.mark.parametrize("label,urdf,base,tip", ALL_URDFS, ids=[c[0] for c in ALL_URDFS])
def test_every_urdf_round_trips(dynid_cli, tmp_path, label, urdf, base, tip):
    """identify on a short run of Pinocchio's torques writes identified.urdf whose XML tree equals the source's
    outside the moving links' <inertial> and the chain joints' <dynamics> (comments, names, order, meshes, limits,
    every other element), and Pinocchio on it equals `dynid torque --params` (rigid part) to 1e-9. 8 s of a
    multi-sine at 100 Hz: enough to identify something; only that the file carries it is checked."""
    if not Path(urdf).is_absolute():
        robots = check_urdf.robots_dir(None)
        assert robots, "example-robot-data not installed — run scripts/test.sh"
        urdf = str(robots / urdf)
    case = check_urdf.Case(label, urdf, base, tip)
    summary = check_urdf.import_case(dynid_cli, Path("/"), case, tmp_path / "imported")
    chain = summary["chain"]
    table = tomllib.loads(Path(summary["dh"]).read_text())
    span = np.array([1.0 if j["kind"] == "revolute" else 0.1 for j in table["joint"]])
    for name, seed in (("train", 1), ("val", 2)):
        write_run(tmp_path / f"{name}.csv", Path(urdf), chain, seed, 8.0, span)
    # With --base/--tip the chain is the TOML import-urdf wrote (it records the URDF and the options).
    arm = summary["dh"] if base or tip else urdf
    out = tmp_path / "id"
    cmd = [dynid_cli, "identify", "--arm", arm, "--data", str(tmp_path / "train.csv")]
    cmd += ["--validate", str(tmp_path / "val.csv"), "--effects", "viscous,coulomb", "--out", str(out)]
    subprocess.run(cmd, check=True, capture_output=True)
    written = out / "identified.urdf"
    assert written.is_file(), f"{label}: no identified.urdf"

    moving = moving_links(ET.parse(urdf).getroot(), chain[0])
    diff = same_tree(tree(written, moving, set(chain)), tree(Path(urdf), moving, set(chain)))
    assert diff is None, f"{label}: identified.urdf differs outside the replaced elements: {diff}"
    prolog = written.read_text().split("<robot", 1)[0]
    assert prolog == Path(urdf).read_text().split("<robot", 1)[0], f"{label}: the text before <robot> changed"

    params = rigid(out / "identified.params.toml", tmp_path / "rigid.params.toml")
    states = check_urdf.random_states(table, 20, np.random.default_rng(3))
    ours = check_urdf.dynid_torques(dynid_cli, arm, params, states, tmp_path)
    ref = check_urdf.pinocchio_torques(written, chain, states)
    err = check_urdf.max_relative(ours, ref)
    assert err < 1e-9, f"{label}: Pinocchio on identified.urdf vs dynid torque: max rel {err:.2e}"
