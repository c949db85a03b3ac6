"""Check `dynid import-urdf` against Pinocchio on the URDFs of the PyPI package example-robot-data.

For each case: `dynid import-urdf ROBOT.urdf [--base B] [--tip T] --out TMP --json`, then `dynid torque` on random
states (q, dq, ddq) through the reference RNEA (`--arm TMP/NAME.toml`) and, with `--kernels`, through the generated
kernels of a throw-away copy of the crate with the imported arms dropped into `arms/`. Pinocchio's `rnea` on the same
URDF (`buildModelFromUrdf`, fixed base; joints off the chain locked at 0 with `buildReducedModel`) is the reference.
The error of a state is max|tau_dynid - tau_pin| / max|tau_pin|; the worst over all states must be below --tol.
Also: `dynid export-urdf` of the imported arm, read back by Pinocchio, gives the same torques.

    python3 tests/pinocchio/check_urdf.py --dynid target/debug/dynid            # all cases
    python3 tests/pinocchio/check_urdf.py --dynid target/debug/dynid --case ur5 --samples 50
    python3 tests/pinocchio/check_urdf.py --dynid target/debug/dynid --kernels  # + generated kernels (minutes)
    python3 tests/pinocchio/check_urdf.py --check                               # prerequisites only

Exit status: 0 all agree, 1 a disagreement or a failed command, 77 pinocchio or example-robot-data missing.
Install: scripts/test.sh sets up .venv/ with everything (or: pip install -r requirements.txt)
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

SKIP = 77
INSTALL = "run scripts/test.sh (it sets up .venv/ with it), or pip install -r requirements.txt"
REPO = Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class Case:
    """One import: a URDF of example-robot-data (relative to its robots/ folder) and the chain options."""

    label: str
    urdf: str
    base: str | None = None
    tip: str | None = None
    why: str = ""


# The three robots first, then other vendors: 5-7 joints, continuous joints, axes along -y or unaligned,
# grippers and hands at the tip (locked and lumped), an arm taken out of a larger tree with --base/--tip.
CASES: list[Case] = [
    Case("ur5", "ur_description/urdf/ur5_robot.urdf", why="UR5, 6 joints"),
    Case("panda", "panda_description/urdf/panda.urdf", why="Panda, default chain: hand and mimic fingers lumped"),
    Case("panda_link8", "panda_description/urdf/panda.urdf", tip="panda_link8", why="Panda up to the flange"),
    Case("panda_hand", "panda_description/urdf/panda.urdf", tip="panda_hand", why="Panda up to the hand"),
    Case("double_pendulum", "double_pendulum_description/urdf/double_pendulum.urdf", why="axes along x"),
    Case("double_pendulum_continuous", "double_pendulum_description/urdf/double_pendulum_continuous.urdf"),
    Case("double_pendulum_simple", "double_pendulum_description/urdf/double_pendulum_simple.urdf"),
    Case("ur3_gripper", "ur_description/urdf/ur3_gripper.urdf", why="gripper at the tip"),
    Case("ur5_gripper", "ur_description/urdf/ur5_gripper.urdf", why="gripper at the tip"),
    Case("ur10", "ur_description/urdf/ur10_robot.urdf"),
    Case("kinova", "kinova_description/robots/kinova.urdf", why="Kinova, continuous joints, fingers"),
    Case("xarm7", "xarm_description/urdf/xarm7.urdf", why="UFactory xArm 7"),
    Case("z1", "z1_description/urdf/z1.urdf", why="Unitree Z1, gripper joint"),
    Case("so100", "so_arm_description/urdf/so100.urdf", why="SO-100, unaligned axes"),
    Case("so101", "so_arm_description/urdf/so101.urdf", why="SO-101, unaligned axes"),
    Case("finger_edu", "finger_edu_description/robots/finger_edu.urdf", why="TriFinger finger, axes along -y"),
    Case("asr_twodof", "asr_twodof_description/urdf/TwoDofs.urdf"),
    Case("talos_left_arm", "talos_data/robots/talos_left_arm.urdf", why="TALOS arm with hand"),
    Case(
        "tiago_arm",
        "tiago_description/robots/tiago_no_hand.urdf",
        base="torso_lift_link",
        tip="arm_7_link",
        why="arm out of a mobile manipulator",
    ),
    Case(
        "tiago_torso_arm",
        "tiago_description/robots/tiago_no_hand.urdf",
        base="base_link",
        tip="arm_7_link",
        why="prismatic torso lift + 7-joint arm, head locked",
    ),
    Case(
        "pr2_left_arm",
        "pr2_description/urdf/pr2.urdf",
        base="base_link",
        tip="l_gripper_palm_link",
        why="PR2: prismatic torso + left arm with continuous rolls; other arm, head, grippers locked",
    ),
    Case(
        "baxter_left",
        "baxter_description/urdf/baxter.urdf",
        base="torso",
        tip="left_gripper",
        why="one arm of a two-arm robot",
    ),
]


# reference: `dynid torque --arm NAME.toml` (reference RNEA); kernels: `dynid torque --arm NAME` built with the arm in
# arms/; export: Pinocchio on `dynid export-urdf` of the imported arm.
COLUMNS = ("reference", "kernels", "export")


@dataclass
class Result:
    case: Case
    dof: int = 0
    max_rel: dict[str, float] = field(default_factory=dict)
    error: str | None = None


def robots_dir(given: str | None) -> Path | None:
    """The robots/ folder of example-robot-data (cmeel wheel layout, or the older Python module)."""
    if given:
        return Path(given)
    if env := os.environ.get("EXAMPLE_ROBOT_DATA_ROBOTS"):
        return Path(env)
    try:
        from importlib.metadata import PackageNotFoundError, distribution

        try:
            dist = distribution("example-robot-data")
            path = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))
            if path.is_dir():
                return path
        except PackageNotFoundError:
            pass
        import example_robot_data  # type: ignore[import-not-found]  # older releases ship a module

        path = Path(example_robot_data.getModelPath("ur_description/urdf/ur5_robot.urdf")) / "robots"
        return path if path.is_dir() else None
    except ImportError:
        return None


def run(cmd: list[str], **kw: object) -> subprocess.CompletedProcess[str]:
    proc = subprocess.run(cmd, capture_output=True, text=True, **kw)  # type: ignore[call-overload]
    if proc.returncode != 0:
        raise RuntimeError(f"`{' '.join(cmd)}` failed ({proc.returncode}):\n{proc.stderr.strip()}")
    return proc


def import_case(dynid: str, robots: Path, case: Case, out: Path) -> dict:
    cmd = [dynid, "import-urdf", str(robots / case.urdf), "--name", case.label, "--out", str(out), "--json"]
    if case.base:
        cmd += ["--base", case.base]
    if case.tip:
        cmd += ["--tip", case.tip]
    return json.loads(run(cmd).stdout)


def random_states(table: dict, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Rows of q, dq, ddq; revolute q over a full turn, prismatic q within +-0.2 m."""
    kinds = [j["kind"] for j in table["joint"]]
    n = len(kinds)
    rows = np.empty((samples, 3 * n))
    for i, kind in enumerate(kinds):
        span = math.pi if kind == "revolute" else 0.2
        rows[:, i] = rng.uniform(-span, span, samples)
    rows[:, n:] = rng.uniform(-2.0, 2.0, (samples, 2 * n))
    return rows


def pinocchio_torques(urdf: Path, chain: list[str], states: np.ndarray) -> np.ndarray:
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(urdf))
    names = list(model.names)[1:]
    missing = [j for j in chain if j not in names]
    if missing:
        raise RuntimeError(f"chain joints unknown to pinocchio: {missing}")
    lock = [model.getJointId(j) for j in names if j not in chain]
    reduced = pin.buildReducedModel(model, lock, pin.neutral(model)) if lock else model
    if list(reduced.names)[1:] != chain:
        raise RuntimeError(f"joint order differs: pinocchio {list(reduced.names)[1:]} vs dynid {chain}")
    data = reduced.createData()
    n = len(chain)
    taus = np.empty((len(states), n))
    for k, row in enumerate(states):
        q = []
        for i, joint in enumerate(reduced.joints[1:]):
            angle = row[i]
            q += [math.cos(angle), math.sin(angle)] if joint.nq == 2 else [angle]
        taus[k] = pin.rnea(reduced, data, np.array(q), row[n : 2 * n], row[2 * n :])
    return taus


def dynid_torques(dynid: str, arm: str, params: Path, states: np.ndarray, work: Path) -> np.ndarray:
    n = states.shape[1] // 3
    data = work / "states.csv"
    with data.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t"] + [f"{b}{i}" for b in ("q", "dq", "ddq") for i in range(1, n + 1)])
        for k, row in enumerate(states):
            w.writerow([repr(float(k))] + [repr(float(x)) for x in row])
    out = work / "tau.csv"
    run([dynid, "torque", "--arm", arm, "--params", str(params), "--data", str(data), "--out", str(out)])
    with out.open() as f:
        rows = list(csv.reader(f))[1:]
    return np.array([[float(x) for x in r[1:]] for r in rows])


def max_relative(ours: np.ndarray, ref: np.ndarray) -> float:
    scale = np.maximum(np.abs(ref).max(axis=1), 1e-300)
    return float((np.abs(ours - ref).max(axis=1) / scale).max())


def build_kernels(arms: list[Path]) -> str:
    """A copy of the crate with `arms` added to arms/, built (build.rs runs the generator); its dynid binary."""
    copy = Path(tempfile.mkdtemp(prefix="dynid-kernels-"))
    ignore = shutil.ignore_patterns("target", ".git", "__pycache__", "*.pyc")
    for item in REPO.iterdir():
        if item.name in {"target", ".git"}:
            continue
        if item.is_dir():
            shutil.copytree(item, copy / item.name, ignore=ignore)
        else:
            shutil.copy2(item, copy / item.name)
    for toml in arms:
        shutil.copy2(toml, copy / "arms" / toml.name)
    env = dict(os.environ, CARGO_TARGET_DIR=str(REPO / "target" / "urdf-kernels"))
    t0 = time.time()
    run(["cargo", "build", "--quiet", "--bin", "dynid"], cwd=copy, env=env)
    print(f"built the crate copy with {len(arms)} imported arms in {time.time() - t0:.0f} s", file=sys.stderr)
    shutil.rmtree(copy, ignore_errors=True)
    binary = str(REPO / "target" / "urdf-kernels" / "debug" / "dynid")
    listed = {arm["name"] for arm in json.loads(run([binary, "arms", "--json"]).stdout)}
    missing = [toml.stem for toml in arms if toml.stem not in listed]
    if missing:
        raise RuntimeError(f"`dynid arms` of the built copy does not list {missing}")
    return binary


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dynid", default=str(REPO / "target" / "debug" / "dynid"), help="the dynid binary")
    ap.add_argument("--robots", help="example-robot-data's robots/ folder (default: found from the package)")
    ap.add_argument("--case", action="append", help="run only these cases (repeatable)")
    ap.add_argument("--samples", type=int, default=20)
    ap.add_argument("--tol", type=float, default=1e-9)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--kernels", action="store_true", help="also compare the generated kernels (builds a crate copy)")
    ap.add_argument("--check", action="store_true", help="only check that the prerequisites are installed")
    ap.add_argument("--json", action="store_true", help="print the results as JSON")
    args = ap.parse_args(argv)

    try:
        import pinocchio  # noqa: F401
    except ImportError:
        print(f"skip: pinocchio is not installed — {INSTALL}", file=sys.stderr)
        return SKIP
    robots = robots_dir(args.robots)
    if robots is None or not robots.is_dir():
        print(f"skip: example-robot-data is not installed — {INSTALL}")
        return SKIP
    if args.check:
        return 0

    known = {c.label: c for c in CASES}
    unknown = [c for c in args.case or [] if c not in known]
    if unknown:
        print(f"error: unknown case(s) {unknown}; known: {', '.join(known)}", file=sys.stderr)
        return 2
    cases = [known[c] for c in args.case] if args.case else CASES
    rng = np.random.default_rng(args.seed)
    results: list[Result] = []
    with tempfile.TemporaryDirectory(prefix="dynid-urdf-") as tmp:
        work = Path(tmp)
        imported: list[tuple[Result, dict, dict, np.ndarray, np.ndarray]] = []
        for case in cases:
            res = Result(case)
            results.append(res)
            try:
                summary = import_case(args.dynid, robots, case, work)
                table = tomllib.loads(Path(summary["dh"]).read_text())
                res.dof = summary["dof"]
                states = random_states(table, args.samples, rng)
                ref = pinocchio_torques(robots / case.urdf, summary["chain"], states)
                ours = dynid_torques(args.dynid, summary["dh"], Path(summary["params"]), states, work)
                res.max_rel["reference"] = max_relative(ours, ref)
                # export-urdf of the imported arm, read by Pinocchio itself, must be the same robot.
                exported = work / f"{case.label}.urdf"
                run(
                    [args.dynid, "export-urdf", "--arm", summary["dh"], "--params", summary["params"]]
                    + ["--out", str(exported)]
                )
                joints = [f"joint{i}" for i in range(1, res.dof + 1)]
                res.max_rel["export"] = max_relative(pinocchio_torques(exported, joints, states), ref)
                imported.append((res, summary, table, states, ref))
            except (RuntimeError, OSError, ValueError, KeyError) as err:
                res.error = str(err)
        if args.kernels and imported:
            try:
                binary = build_kernels([Path(s["dh"]) for _, s, _, _, _ in imported])
                for res, summary, _, states, ref in imported:
                    ours = dynid_torques(binary, summary["name"], Path(summary["params"]), states, work)
                    res.max_rel["kernels"] = max_relative(ours, ref)
            except (RuntimeError, OSError, ValueError) as err:
                for res, *_ in imported:
                    res.error = f"generated kernels: {err}"

    failed = [r for r in results if r.error or any(v > args.tol for v in r.max_rel.values())]
    if args.json:
        rows = [
            {"case": r.case.label, "urdf": r.case.urdf, "dof": r.dof, "max_rel": r.max_rel, "error": r.error}
            for r in results
        ]
        print(json.dumps(rows, indent=2))
    else:
        head = "  ".join(f"{k:>10}" for k in COLUMNS)
        print(f"{'case':<28} {'dof':>3}  {head}  (max relative torque error vs pinocchio)")
        for r in results:
            cells = "  ".join(f"{r.max_rel[k]:>10.1e}" if k in r.max_rel else f"{'-':>10}" for k in COLUMNS)
            flag = "" if r not in failed else "  FAIL" + (f": {r.error}" if r.error else f" (tol {args.tol:g})")
            print(f"{r.case.label:<28} {r.dof:>3}  {cells}{flag}")
    print(f"{len(results) - len(failed)} passed, {len(failed)} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
