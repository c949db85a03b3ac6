"""Type stubs of dynid (the native module dynid._dynid plus the pure-Python part in __init__.py)."""

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

__version__: str

_Array = npt.NDArray[np.float64]
_ArrayLike = npt.NDArray[np.float64] | Sequence[float] | Sequence[Sequence[float]]
_Path = str | os.PathLike[str]

class DynidError(ValueError):
    """Bad input (a data file, a D-H table, a URDF, an option): ``file:line: field: what — how to fix``."""

def arms() -> list[str]:
    """Names of the generated arms compiled into this build."""

def read_params(path: _Path, dof: int) -> _Array:
    """Full parameters ``(10·dof,)`` of a params TOML file (``dynid torque --params``)."""

class Arm:
    """A robot arm's rigid-body dynamics: generated kernels (``Arm(name)``) or the reference dynamics of a D-H
    table or URDF that is not compiled in (``Arm.from_dh``, ``Arm.from_urdf``).

    Kernels take float64 arrays ``(n,)`` or ``(N, n)`` (any memory layout) and return ``(n, ...)`` or
    ``(N, n, ...)``; full parameters ``params`` are ``(10·n,)``, per link ``XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M``
    about the link frame's origin. ``threads``: ``None`` = all cores, 1 = the calling thread. ``out``: a
    preallocated C-contiguous float64 array of the output's shape to write into (returned)."""

    def __init__(self, name: str) -> None: ...
    @staticmethod
    def from_dh(path: _Path) -> Arm: ...
    @staticmethod
    def from_urdf(
        path: _Path,
        base: str | None = None,
        tip: str | None = None,
        gravity: Sequence[float] | None = None,
        name: str | None = None,
    ) -> Arm: ...
    @staticmethod
    def kernels() -> list[str]: ...
    @property
    def name(self) -> str: ...
    @property
    def dof(self) -> int: ...
    @property
    def np(self) -> int: ...
    @property
    def nb(self) -> int: ...
    @property
    def generated(self) -> bool: ...
    @property
    def dynamics(self) -> str:
        """``"generated kernels"`` or ``"reference dynamics (not compiled in)"``."""
    @property
    def param_names(self) -> list[str]: ...
    @property
    def base_param_names(self) -> list[str]: ...
    @property
    def base_param_exprs(self) -> list[str]: ...
    @property
    def gravity_vector(self) -> list[float]: ...
    @property
    def dh_toml(self) -> str: ...
    @property
    def base_map(self) -> _Array:
        """``(nb, 10·n)``: ``theta = base_map @ params``."""
    def base_params(self, params: _ArrayLike) -> _Array: ...
    def to_urdf(self, params: _ArrayLike | None = None) -> str: ...
    def regressor(
        self,
        q: _ArrayLike,
        dq: _ArrayLike,
        ddq: _ArrayLike,
        *,
        threads: int | None = None,
        out: _Array | None = None,
    ) -> _Array:
        """``(n, 10·n)`` or ``(N, n, 10·n)``: ``tau = Y @ params``."""
    def base_regressor(
        self,
        q: _ArrayLike,
        dq: _ArrayLike,
        ddq: _ArrayLike,
        *,
        threads: int | None = None,
        out: _Array | None = None,
    ) -> _Array:
        """``(n, nb)`` or ``(N, n, nb)``: ``tau = Yb @ base_params(params)``."""
    def mass_matrix(
        self, q: _ArrayLike, params: _ArrayLike, *, threads: int | None = None, out: _Array | None = None
    ) -> _Array:
        """``(n, n)`` or ``(N, n, n)``."""
    def bias(
        self,
        q: _ArrayLike,
        dq: _ArrayLike,
        params: _ArrayLike,
        *,
        threads: int | None = None,
        out: _Array | None = None,
    ) -> _Array:
        """Coriolis, centrifugal and gravity torques, ``(n,)`` or ``(N, n)``."""
    def gravity(
        self, q: _ArrayLike, params: _ArrayLike, *, threads: int | None = None, out: _Array | None = None
    ) -> _Array:
        """``(n,)`` or ``(N, n)``."""
    def inverse_dynamics(
        self,
        q: _ArrayLike,
        dq: _ArrayLike,
        ddq: _ArrayLike,
        params: _ArrayLike,
        *,
        threads: int | None = None,
        out: _Array | None = None,
    ) -> _Array:
        """``tau = M(q) ddq + h(q, dq)``, ``(n,)`` or ``(N, n)``."""
    def forward_dynamics(
        self, q: _ArrayLike, dq: _ArrayLike, tau: _ArrayLike, params: _ArrayLike, *, threads: int | None = None
    ) -> _Array:
        """``ddq = M(q)⁻¹ (tau − h(q, dq))``, ``(n,)`` or ``(N, n)``."""
    def inverse_mass_matrix(self, q: _ArrayLike, params: _ArrayLike, *, threads: int | None = None) -> _Array:
        """``M(q)⁻¹``, ``(n, n)`` or ``(N, n, n)``."""
    def inverse_dynamics_derivatives(
        self, q: _ArrayLike, dq: _ArrayLike, ddq: _ArrayLike, params: _ArrayLike, *, threads: int | None = None
    ) -> tuple[_Array, _Array]:
        """``(∂tau/∂q, ∂tau/∂dq)``, each ``(n, n)`` or ``(N, n, n)`` (rows: outputs, columns: inputs)."""
    def forward_dynamics_derivatives(
        self, q: _ArrayLike, dq: _ArrayLike, tau: _ArrayLike, params: _ArrayLike, *, threads: int | None = None
    ) -> tuple[_Array, _Array, _Array]:
        """``(∂ddq/∂q, ∂ddq/∂dq, M⁻¹)``, each ``(n, n)`` or ``(N, n, n)``."""
    def __eq__(self, other: object) -> bool: ...
    def __reduce__(self) -> tuple[Any, tuple[str, str, str, str]]: ...

@dataclass(frozen=True)
class IdentifyResult:
    report: dict[str, Any]
    report_dir: Path | None = None
    files: list[str] = ...
    warnings: list[str] = ...
    @property
    def arm(self) -> str: ...
    @property
    def effects_found(self) -> list[dict[str, Any]]: ...
    @property
    def parameters(self) -> list[dict[str, Any]]: ...
    @property
    def effects(self) -> list[dict[str, Any]]: ...
    @property
    def errors(self) -> dict[str, Any]: ...
    @property
    def cutoff_hz(self) -> float: ...
    @property
    def fixed(self) -> list[str]: ...
    @property
    def undetermined(self) -> list[dict[str, Any]]: ...

def identify(
    arm: Arm | _Path,
    data: Any,
    validate: Any = None,
    effects: str | Sequence[str] = "auto",
    cutoff: float | str = "auto",
    *,
    smoothing: str = "auto",
    derivative: str = "butterworth",
    file_velocity: bool = True,
    physical: bool = True,
    prior: _Path | None = None,
    strict: bool = False,
    out: _Path | None = None,
    topic: str | None = None,
    joints: Sequence[str] | None = None,
    torque_scale: Sequence[float] | None = None,
) -> IdentifyResult:
    """``dynid identify`` on file paths, 2-D float64 arrays, dicts of columns or pandas DataFrames."""

@dataclass(frozen=True)
class ImportedURDF:
    arm: Arm
    dh_toml: str
    params_toml: str
    params: _Array
    chain: list[str]
    notes: list[str]
    warnings: list[str]
    def write(self, directory: _Path) -> tuple[Path, Path]: ...

def import_urdf(
    path: _Path,
    base: str | None = None,
    tip: str | None = None,
    gravity: Sequence[float] | None = None,
    name: str | None = None,
) -> ImportedURDF: ...

class PayloadResult:
    mass: float
    sigma_mass: float
    com: np.ndarray
    sigma_com: np.ndarray
    inertia: np.ndarray
    sigma_inertia: np.ndarray
    params: np.ndarray
    torque_scale: np.ndarray | None
    torque_scale_sigma: np.ndarray | None
    uncalibrated_joints: list[int]
    warnings: list[str]
    files: list[str]
    json: str
    def to_dict(self) -> dict[str, Any]: ...

def payload(
    arm: Arm | str | os.PathLike[str],
    params: str | os.PathLike[str],
    data: Any,
    unloaded: Any = None,
    *,
    mass: float | None = None,
    torque_scale: Sequence[float] | None = None,
    cutoff: float | str = "auto",
    derivative: str = "butterworth",
    out: str | os.PathLike[str] | None = None,
) -> PayloadResult: ...
