"""Load an ``arms/<arm>.toml`` modified (Craig) D-H table.

The Rust loader (``src/dh.rs``) is the user-facing validator with detailed messages; this one checks what the
generator relies on and fails with the file and field named.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

# Within this distance of a multiple of pi/2 an angle's cosine and sine are taken as exact 0/+-1, so that
# rotations by +-90 degrees become signed permutations in the generated code (zero propagation).
SNAP_TOL = 1e-9


class DhError(ValueError):
    """An ``arms/*.toml`` file the generator cannot use."""


@dataclass(frozen=True)
class Joint:
    kind: str  # "revolute" | "prismatic"
    alpha: float
    a: float
    d: float
    theta: float


@dataclass(frozen=True)
class DhTable:
    name: str
    gravity: tuple[float, float, float]
    joints: tuple[Joint, ...]

    @property
    def dof(self) -> int:
        return len(self.joints)


def cos_sin(angle: float) -> tuple[float, float]:
    """Cosine and sine, exact (0, +-1) near multiples of pi/2."""
    k = round(angle / (math.pi / 2))
    if abs(angle - k * math.pi / 2) < SNAP_TOL:
        return [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)][k % 4]
    return math.cos(angle), math.sin(angle)


def _number(path: Path, where: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise DhError(f"{path}: {where}: expected a number, got {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise DhError(f"{path}: {where}: must be finite, got {value!r}")
    return x


def load(path: Path) -> DhTable:
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise DhError(f"{path}: {err}") from err
    name = doc.get("name", path.stem)
    if doc.get("convention", "modified") != "modified":
        raise DhError(f'{path}: convention: only "modified" (Craig) D-H is supported')
    gravity = doc.get("gravity", [0.0, 0.0, -9.81])
    if not isinstance(gravity, list) or len(gravity) != 3:
        raise DhError(f"{path}: gravity: expected [gx, gy, gz] in m/s^2")
    g = tuple(_number(path, f"gravity[{i}]", v) for i, v in enumerate(gravity))
    rows = doc.get("joint", [])
    if not rows:
        raise DhError(f"{path}: no [[joint]] tables")
    joints = []
    for i, row in enumerate(rows, start=1):
        kind = row.get("kind", "revolute")
        if kind not in ("revolute", "prismatic"):
            raise DhError(f'{path}: joint {i}: kind must be "revolute" or "prismatic", got {kind!r}')
        vals = {k: _number(path, f"joint {i}: {k}", row.get(k, 0.0)) for k in ("alpha", "a", "d", "theta")}
        joints.append(Joint(kind, **vals))
    return DhTable(str(name), g, tuple(joints))  # type: ignore[arg-type]
