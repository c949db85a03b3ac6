"""Shared helpers of the dynid Python tests: random physical parameters, random states, Pinocchio models of
dynid's arms (built from dynid's own URDF export, whose links are the D-H frames), the CLI binary."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]


def plausible_params(n: int, rng: np.random.Generator) -> np.ndarray:
    """Physically consistent full parameters (dynid order XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M per link, about
    the link frame's origin): mass in [1, 5] kg, centre of mass within 0.15 m, a rotated inertia about the centre
    of mass with principal moments that satisfy the triangle inequality."""
    p = []
    for _ in range(n):
        m = rng.uniform(1.0, 5.0)
        c = rng.uniform(-0.15, 0.15, 3)
        d = rng.uniform(0.01, 0.1, 3)
        moments = np.array([d[0] + d[1], d[1] + d[2], d[0] + d[2]])
        r, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        ic = r @ np.diag(moments) @ r.T
        io = ic + m * (c @ c * np.eye(3) - np.outer(c, c))
        p += [io[0, 0], io[0, 1], io[0, 2], io[1, 1], io[1, 2], io[2, 2], *(m * c), m]
    return np.array(p)


def random_states(arm, samples: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q ~ U(-pi, pi) (prismatic: U(-0.5, 0.5) m), dq ~ U(-2, 2), ddq ~ U(-5, 5)."""
    import tomllib

    kinds = [j["kind"] for j in tomllib.loads(arm.dh_toml)["joint"]]
    span = np.array([np.pi if k == "revolute" else 0.5 for k in kinds])
    q = rng.uniform(-1.0, 1.0, (samples, arm.dof)) * span
    return q, rng.uniform(-2.0, 2.0, (samples, arm.dof)), rng.uniform(-5.0, 5.0, (samples, arm.dof))


def pin_q(model, q: np.ndarray) -> np.ndarray:
    """Pinocchio's configuration of joint angles q: (cos, sin) for a continuous joint, the value otherwise."""
    out: list[float] = []
    for joint, angle in zip(model.joints[1:], q):
        out += [np.cos(angle), np.sin(angle)] if joint.nq == 2 else [angle]
    return np.array(out)


# Pinocchio's dynamic parameters of a body are (m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz) about the joint
# frame's origin; dynid's are (XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M) about the link frame's origin, which the
# exported URDF makes the joint frame. dynid column k of a link is Pinocchio column PIN_OF[k].
PIN_OF = [4, 5, 7, 6, 8, 9, 1, 2, 3, 0]


def pin_columns(n: int) -> list[int]:
    return [10 * i + k for i in range(n) for k in PIN_OF]


def rel_err(got: np.ndarray, want: np.ndarray) -> float:
    """max |got - want| / max |want| (1 when want is all zero, so a zero reference is not a free pass)."""
    scale = float(np.max(np.abs(want))) or 1.0
    return float(np.max(np.abs(got - want))) / scale


@pytest.fixture(scope="session")
def dynid_cli() -> str:
    """The CLI binary: $DYNID_CLI (scripts/test.sh points it at the one `cargo test` built), else a release
    build from this checkout."""
    if path := os.environ.get("DYNID_CLI"):
        assert Path(path).is_file(), f"DYNID_CLI={path} does not exist — run cargo build or unset it"
        return path
    cargo = shutil.which("cargo")
    assert cargo, "cargo not found — the CLI comparison needs the Rust toolchain (or DYNID_CLI=path/to/dynid)"
    subprocess.run([cargo, "build", "--release", "--bin", "dynid"], cwd=REPO, check=True)
    return str(REPO / "target" / "release" / "dynid")
