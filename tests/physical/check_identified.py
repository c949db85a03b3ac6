"""Check the model `dynid identify` hands out against libraries that share none of its code.

Given an identification's output directory (`identified.params.toml`, `identified.urdf`, `report.json`):

1. numpy: every link's pseudo-inertia J = [[tr(I)/2 - I, h], [h^T, m]] (from the params file's inertia about the
   link origin, h = m*com) has no eigenvalue below -1e-9 * its largest: the links are possible rigid bodies.
2. Pinocchio: `identified.urdf` loads; on random states its `rnea`, plus the joint friction Pinocchio read from the
   URDF (`damping * v + friction * s(v)`, s the params file's smoothed sign) and the effects URDF cannot carry
   (from the params file), equals `dynid torque --params identified.params.toml` to --tol (max relative).
3. MuJoCo: `identified.urdf` loads; its body masses, joint damping and friction loss are the params file's; with
   damping, friction and joint limits switched off, `mj_inverse` equals Pinocchio's `rnea` to --tol.

    python tests/physical/check_identified.py --dynid target/release/dynid --arm ARM --report OUT_DIR

Exit status: 0 all agree, 1 a disagreement, 77 a library missing (scripts/test.sh installs them into .venv/).
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

import numpy as np

SKIP = 77


def pseudo_inertia(m: float, com: list[float], io: list[float]) -> np.ndarray:
    """J of one link from its mass, centre of mass and inertia tensor about the link origin."""
    xx, xy, xz, yy, yz, zz = io
    inertia = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    h = m * np.asarray(com)
    j = np.zeros((4, 4))
    j[:3, :3] = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    j[:3, 3] = h
    j[3, :3] = h
    j[3, 3] = m
    return j


def check_eigenvalues(params: dict) -> list[str]:
    problems = []
    for i, link in enumerate(params["link"], start=1):
        ev = np.linalg.eigvalsh(pseudo_inertia(link["m"], link["com"], link["inertia_origin"]))
        scale = max(abs(ev).max(), 1e-300)
        print(f"link {i}: pseudo-inertia eigenvalues {ev} (smallest/largest {ev[0] / scale:.2e})")
        if ev[0] < -1e-9 * scale:
            problems.append(f"link {i}: pseudo-inertia eigenvalue {ev[0]:e} < 0: not a rigid body")
    return problems


def friction_spline(params: dict, v: np.ndarray, n: int) -> np.ndarray:
    """`spline_a·N1 + spline_b·N2 + spline_c·N3` at x = q̇ / spline_velocity: the natural cubic spline basis of Hastie,
    Tibshirani & Friedman (ESL eq. 5.4-5.5) on knots -1, -1/2, 0, 1/2, 1, each column scaled to 1 at x = 1 (the params
    format's definition, written here from it)."""
    knots = [-1.0, -0.5, 0.0, 0.5, 1.0]
    x = v / effect(params, "spline_velocity", n, 1.0)

    def d(k: int, x: np.ndarray) -> np.ndarray:
        return (np.maximum(x - knots[k], 0) ** 3 - np.maximum(x - knots[-1], 0) ** 3) / (knots[-1] - knots[k])

    def column(k: int, x: np.ndarray) -> np.ndarray:
        one = np.ones(1)
        return (d(k, x) - d(3, x)) / (d(k, one) - d(3, one))

    return sum(effect(params, key, n) * column(k, x) for k, key in enumerate(["spline_a", "spline_b", "spline_c"]))


def effect(params: dict, key: str, n: int, default: float = 0.0) -> np.ndarray:
    return np.asarray(params.get("effects", {}).get(key, [default] * n), dtype=float)


def smooth_sign(v: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """tanh(v / vel) per joint (column); the exact sign where vel = 0."""
    out = np.sign(v)
    for j in np.flatnonzero(vel > 0):
        out[:, j] = np.tanh(v[:, j] / vel[j])
    return out


def pin_q(model, q: np.ndarray) -> np.ndarray:  # noqa: ANN001
    """Pinocchio's configuration: (cos, sin) for a continuous joint."""
    out = []
    for joint, angle in zip(list(model.joints)[1:], q, strict=True):
        out += [math.cos(angle), math.sin(angle)] if joint.nq == 2 else [angle]
    return np.array(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dynid", required=True)
    ap.add_argument("--arm", required=True)
    ap.add_argument("--report", required=True, type=Path)
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--tol", type=float, default=1e-9)
    a = ap.parse_args(argv)
    try:
        import mujoco
        import pinocchio as pin
    except ImportError as e:
        print(f"missing: {e} — run scripts/test.sh (it sets up .venv/)", file=sys.stderr)
        return SKIP

    params_path, urdf = a.report / "identified.params.toml", a.report / "identified.urdf"
    params = tomllib.loads(params_path.read_text())
    n = len(params["link"])
    problems = check_eigenvalues(params)

    rng = np.random.default_rng(7)
    q = rng.uniform(-math.pi, math.pi, (a.samples, n))
    v = rng.uniform(-2, 2, (a.samples, n))
    acc = rng.uniform(-2, 2, (a.samples, n))
    with tempfile.TemporaryDirectory() as tmp:
        states, out = Path(tmp) / "states.csv", Path(tmp) / "tau.csv"
        head = ["t"] + [f"{c}{j + 1}" for c in ("q", "dq", "ddq") for j in range(n)]
        rows = [",".join(head)]
        for k in range(a.samples):
            rows.append(",".join(repr(float(x)) for x in [k * 0.01, *q[k], *v[k], *acc[k]]))
        states.write_text("\n".join(rows) + "\n")
        cmd = [a.dynid, "torque", "--arm", a.arm, "--params", str(params_path)]
        subprocess.run([*cmd, "--data", str(states), "--out", str(out)], check=True)
        ours = np.loadtxt(out, delimiter=",", skiprows=1)[:, 1:]

    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    rigid = np.array([pin.rnea(model, data, pin_q(model, q[k]), v[k], acc[k]) for k in range(a.samples)])
    sv = effect(params, "sign_velocity", n)
    sgn = smooth_sign(v, sv)
    stribeck_v = effect(params, "stribeck_velocity", n, 0.1)
    extra = (
        np.asarray(model.damping) * v
        + np.asarray(model.friction) * sgn
        + effect(params, "asym_coulomb", n) * np.abs(sgn)
        + effect(params, "stribeck", n) * sgn * np.exp(-((v / stribeck_v) ** 2))
        + effect(params, "armature", n) * acc
        + effect(params, "offset", n)
        + effect(params, "spring", n) * q
        + effect(params, "ripple_sin", n) * np.sin(effect(params, "ripple_wavenumber", n) * q)
        + effect(params, "ripple_cos", n) * np.cos(effect(params, "ripple_wavenumber", n) * q)
        + friction_spline(params, v, n)
    )
    u = rigid + extra
    mu = effect(params, "loadcoulomb", n)
    theirs = u + mu * sgn * np.abs(u)
    err = np.abs(ours - theirs).max() / np.abs(theirs).max()
    print(f"Pinocchio rnea + URDF friction + params effects vs dynid torque: max relative {err:.2e} (tol {a.tol:g})")
    if not err <= a.tol:
        problems.append(f"Pinocchio disagrees with dynid torque: {err:.2e}")

    mj = mujoco.MjModel.from_xml_path(str(urdf))
    masses = [link["m"] for link in params["link"]]
    moving = [m for m in mj.body_mass[1:] if m > 0]
    if not np.allclose(moving, masses, rtol=1e-12, atol=0):
        problems.append(f"MuJoCo body masses {moving} != params {masses}")
    for name, got, want in (
        ("damping", mj.dof_damping, effect(params, "viscous", n)),
        ("frictionloss", mj.dof_frictionloss, effect(params, "coulomb", n)),
    ):
        if not np.allclose(got, want, rtol=1e-12, atol=0):
            problems.append(f"MuJoCo {name} {got} != params {want}")
    mj.dof_damping[:] = 0.0
    mj.dof_frictionloss[:] = 0.0
    # The random states leave the joints' ranges: no limit forces in the inverse dynamics.
    mj.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    md = mujoco.MjData(mj)
    worst = 0.0
    for k in range(a.samples):
        md.qpos[:], md.qvel[:], md.qacc[:] = q[k], v[k], acc[k]
        mujoco.mj_inverse(mj, md)
        worst = max(worst, np.abs(md.qfrc_inverse - rigid[k]).max() / np.abs(rigid).max())
    print(f"MuJoCo mj_inverse vs Pinocchio rnea on identified.urdf: max relative {worst:.2e}")
    if not worst <= a.tol:
        problems.append(f"MuJoCo disagrees with Pinocchio: {worst:.2e}")

    for p in problems:
        print(f"FAIL: {p}", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
