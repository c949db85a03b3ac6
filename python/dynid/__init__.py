"""dynid from Python: generated robot dynamics kernels and dynamic-parameter identification.

    >>> import numpy as np, dynid
    >>> arm = dynid.Arm("puma560")
    >>> Q = np.zeros((1000, arm.dof))
    >>> arm.base_regressor(Q, Q, Q).shape
    (1000, 6, 36)

``Arm`` (kernels on numpy arrays), ``identify`` (the CLI's ``dynid identify`` on files, arrays or
DataFrames), ``import_urdf`` (a URDF chain as a D-H table and parameters), ``arms`` (the arms
compiled in). Errors in the input are ``DynidError`` (a ``ValueError``) with the CLI's messages:
``file:line: field: what — how to fix``.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ._dynid import Arm, DynidError, PayloadResult, __version__, arms, read_params
from ._dynid import _identify as _native_identify
from ._dynid import _import_urdf as _native_import_urdf
from ._dynid import _payload as _native_payload

__all__ = [
    "Arm",
    "DynidError",
    "IdentifyResult",
    "ImportedURDF",
    "PayloadResult",
    "__version__",
    "arms",
    "identify",
    "import_urdf",
    "payload",
    "read_params",
]


def _as_arm(arm: Arm | str | os.PathLike[str]) -> Arm:
    if isinstance(arm, Arm):
        return arm
    if isinstance(arm, (str, os.PathLike)):
        return Arm(os.fspath(arm))
    raise TypeError(f"arm: expected a dynid.Arm, an arm name or a D-H table path, got {type(arm).__name__}")


def _canonical_names(dof: int, width: int, label: str) -> list[str]:
    """Column names of a bare 2-D array, by its width: t, q, [dq, [ddq]], tau."""
    blocks = {1 + 2 * dof: ["q", "tau"], 1 + 3 * dof: ["q", "dq", "tau"], 1 + 4 * dof: ["q", "dq", "ddq", "tau"]}
    if width not in blocks:
        raise ValueError(
            f"{label}: a {width}-column array for a {dof}-joint arm — a bare array must have the columns "
            f"t, q1..q{dof}, [dq1..dq{dof}, [ddq1..ddq{dof}]], tau1..tau{dof} in this order "
            f"({1 + 2 * dof}, {1 + 3 * dof} or {1 + 4 * dof} columns); pass a DataFrame or a dict to name them"
        )
    return ["t"] + [f"{b}{j}" for b in blocks[width] for j in range(1, dof + 1)]


def _numeric_block(columns: Sequence[Any], label: str) -> np.ndarray:
    out = []
    for name, col in columns:
        a = np.asarray(col)
        if a.ndim != 1 or a.dtype.kind not in "fiu":
            raise ValueError(
                f"{label}: column `{name}`: expected one number per row, got an array of dtype {a.dtype} "
                f"and shape {a.shape}"
            )
        out.append(a.astype(np.float64, copy=False))
    lengths = {len(a) for a in out}
    if len(lengths) > 1:
        raise ValueError(f"{label}: the columns have different lengths {sorted(lengths)}")
    return np.ascontiguousarray(np.column_stack(out)) if out else np.zeros((0, 0))


def _data_arg(x: Any, label: str, dof: int) -> str | tuple[str, list[str], np.ndarray]:
    """A path as is; an array, dict or DataFrame as (label, column names, C-contiguous float64 block)."""
    if isinstance(x, (str, os.PathLike)):
        return os.fspath(x)
    if hasattr(x, "columns") and hasattr(x, "to_numpy"):  # a pandas DataFrame (no import needed)
        names = [str(c) for c in x.columns]
        values = _numeric_block([(n, x[c].to_numpy()) for n, c in zip(names, x.columns)], label)
        return (f"{label} (DataFrame)", names, values)
    if isinstance(x, Mapping):
        names = [str(k) for k in x]
        return (f"{label} (dict)", names, _numeric_block(list(zip(names, x.values())), label))
    a = np.asarray(x) if isinstance(x, (list, tuple)) else x
    if isinstance(a, np.ndarray):
        if a.dtype != np.float64:
            raise ValueError(f"{label}: expected a float64 array, got dtype {a.dtype}")
        if a.ndim != 2:
            raise ValueError(f"{label}: expected a 2-D array (rows × columns), got shape {a.shape}")
        return (f"{label} (array)", _canonical_names(dof, a.shape[1], label), np.ascontiguousarray(a))
    raise TypeError(
        f"{label}: expected a file path, a 2-D float64 array, a dict of columns or a pandas DataFrame, got "
        f"{type(x).__name__}"
    )


@dataclass(frozen=True)
class IdentifyResult:
    """What ``identify`` found: the report (``report.json``'s document) and handy views of it.

    Attributes: ``report`` (the full JSON document, as a dict), ``report_dir`` (the directory written
    when ``out=`` was given, else ``None``), ``files`` (the files written), ``warnings`` (what the data
    cannot identify). Properties: ``effects_found`` (each with its evidence), ``parameters`` (base
    parameters with value, σ and %σ), ``effects`` (effect coefficients), ``errors`` (relative RMS torque
    errors before/after, training/validation), ``cutoff_hz``, ``fixed`` (base parameters the data cannot see at
    all, held at 0), ``undetermined`` (parameters the data leave free: a one-σ change moves the prediction by more
    than the residual).
    """

    report: dict[str, Any]
    report_dir: Path | None = None
    files: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    @property
    def arm(self) -> str:
        return self.report["arm"]

    @property
    def effects_found(self) -> list[dict[str, Any]]:
        """Effects the search added, in order: ``{"name", "joint", "effect", "evidence"}``."""
        return [{"name": f"{e['effect']}{e['joint']}", **e} for e in self.report["effects_found"]]

    @property
    def parameters(self) -> list[dict[str, Any]]:
        """Base parameters: ``{"name", "expression", "value", "std", "rel_std_percent"}``."""
        return list(self.report["theta"])

    @property
    def effects(self) -> list[dict[str, Any]]:
        """Effect coefficients of the augmented model (same fields plus ``joint``, ``effect``, ``unit``)."""
        return list(self.report["effects"])

    @property
    def errors(self) -> dict[str, Any]:
        """``{"before"|"after": {"train"|"validation": {"per_joint": [...], "overall": x}}}`` (relative RMS)."""
        return {k: self.report["error"][k] for k in ("before", "after")}

    @property
    def cutoff_hz(self) -> float:
        return self.report["data"]["train"][0]["derivative"]["cutoff_hz"]

    @property
    def fixed(self) -> list[str]:
        """Base parameters whose columns are combinations of the others in this data: held at 0, not fitted."""
        return list(self.report["fixed"])

    @property
    def undetermined(self) -> list[dict[str, Any]]:
        """``{"name", "value", "std", "torque_sigma"}`` of each parameter the data leave free."""
        return list(self.report["undetermined"])

    def __repr__(self) -> str:
        found = ", ".join(e["name"] for e in self.effects_found) or "none"
        err = self.errors

        def pct(e: dict[str, Any] | None) -> str:
            return "—" if e is None else f"{100 * e['overall']:.2f} %"

        return (
            f"IdentifyResult(arm={self.arm!r}, effects found: {found}; training {pct(err['before']['train'])} -> "
            f"{pct(err['after']['train'])}, validation {pct(err['before']['validation'])} -> "
            f"{pct(err['after']['validation'])}; {len(self.parameters)} base parameters"
            + (f"; report in {str(self.report_dir)!r})" if self.report_dir else ")")
        )


def identify(
    arm: Arm | str | os.PathLike[str],
    data: Any,
    validate: Any = None,
    effects: str | Sequence[str] = "auto",
    cutoff: float | str = "auto",
    *,
    smoothing: str = "auto",
    coulomb_width: float | str = "auto",
    derivative: str = "butterworth",
    file_velocity: bool = True,
    physical: bool = True,
    prior: str | os.PathLike[str] | None = None,
    strict: bool = False,
    out: str | os.PathLike[str] | None = None,
    topic: str | None = None,
    joints: Sequence[str] | None = None,
    torque_scale: Sequence[float] | None = None,
) -> IdentifyResult:
    """Identify ``arm``'s dynamic parameters from ``data`` — ``dynid identify`` from Python.

    ``data``: one training input or a list of them; each a file path (CSV, ``.csv.gz``, ROS 2 bag
    ``.mcap``), a pandas DataFrame or a dict of columns named as in the CSV (``t, q1..qn, [dq1..],
    [ddq1..], tau1..``, any order), or a 2-D float64 array with those columns in that order.
    ``validate``: one such input, judged with the fitted models. ``effects``: ``"auto"`` (search),
    ``"none"`` or a list such as ``"viscous,coulomb:2"``. ``cutoff``: Hz or ``"auto"``. ``out``: write
    the report there (``report.md``, ``report.json``, plots, ``identified.params.toml``, ...).
    The other keywords are the CLI's flags of the same names (``physical=False`` = ``--physical off``).

    Arrays reach the library as numbers (no text in between) and get every check of the CLI's reader; a row
    is named by its line in the equivalent CSV (line 1 the header, row ``i`` line ``i + 2``). The GIL is
    released while it runs. Raises ``DynidError`` with the CLI's message.
    """
    a = _as_arm(arm)
    items = data if isinstance(data, list) else [data]
    train = [_data_arg(x, f"data[{k}]" if isinstance(data, list) else "data", a.dof) for k, x in enumerate(items)]
    val = None if validate is None else _data_arg(validate, "validate", a.dof)
    effects_text = effects if isinstance(effects, str) else ",".join(effects)

    def shown(x: Any) -> str:
        return repr(x) if isinstance(x, str) else (x[0] if isinstance(x, tuple) else repr(x))

    command = (
        f"dynid.identify({a.name!r}, data=[{', '.join(shown(t) for t in train)}]"
        + (f", validate={shown(val)}" if val is not None else "")
        + f", effects={effects_text!r}, cutoff={cutoff!r}, smoothing={smoothing!r}"
        + (f", out={os.fspath(out)!r})" if out is not None else ")")
    )
    report, files, warns = _native_identify(
        a,
        train,
        val,
        effects_text,
        cutoff,
        smoothing,
        str(coulomb_width),
        derivative,
        file_velocity,
        physical,
        None if prior is None else os.fspath(prior),
        strict,
        None if out is None else os.fspath(out),
        command,
        topic,
        None if joints is None else list(joints),
        None if torque_scale is None else [float(k) for k in torque_scale],
    )
    for w in warns:
        warnings.warn(w, stacklevel=2)
    return IdentifyResult(
        report=report,
        report_dir=None if out is None else Path(out),
        files=list(files),
        warnings=list(warns),
    )


@dataclass(frozen=True)
class ImportedURDF:
    """A URDF serial chain as dynid sees it (``dynid import-urdf``): ``arm`` (reference dynamics),
    ``dh_toml`` and ``params_toml`` (the two files the CLI writes), ``params`` (full parameters,
    ``(10·n,)``, in the D-H link frames), ``chain`` (URDF joint names), ``notes``, ``warnings``."""

    arm: Arm
    dh_toml: str
    params_toml: str
    params: np.ndarray
    chain: list[str]
    notes: list[str]
    warnings: list[str]

    def write(self, directory: str | os.PathLike[str]) -> tuple[Path, Path]:
        """Write ``NAME.toml`` and ``NAME.params.toml`` into ``directory`` (as the CLI does)."""
        d = Path(directory)
        d.mkdir(parents=True, exist_ok=True)
        dh, params = d / f"{self.arm.name}.toml", d / f"{self.arm.name}.params.toml"
        dh.write_text(self.dh_toml)
        params.write_text(self.params_toml)
        return dh, params


def import_urdf(
    path: str | os.PathLike[str],
    base: str | None = None,
    tip: str | None = None,
    gravity: Sequence[float] | None = None,
    name: str | None = None,
) -> ImportedURDF:
    """A URDF's serial chain (``base`` link to ``tip`` link) as a modified D-H table and inertial
    parameters — ``dynid import-urdf`` from Python. Raises ``DynidError`` with the CLI's message."""
    g = None if gravity is None else [float(v) for v in gravity]
    d = _native_import_urdf(os.fspath(path), base, tip, g, name)
    return ImportedURDF(
        arm=d["arm"],
        dh_toml=d["dh_toml"],
        params_toml=d["params_toml"],
        params=d["params"],
        chain=list(d["chain"]),
        notes=list(d["notes"]),
        warnings=list(d["warnings"]),
    )


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
) -> PayloadResult:
    """The flange payload's mass, centre of mass and inertia (last link's frame, each with σ) — ``dynid payload``.

    ``params``: the identified arm (``identified.params.toml``). ``data``: one loaded run or a list (paths, DataFrames,
    dicts or arrays as for ``identify``); ``unloaded``: the same motions without the payload, one per run (aligned in
    time automatically). ``mass``: known mass (kg) — then only COM and inertia, plus ``torque_scale`` per joint.
    ``out``: also write payload.json, payload.params.toml, loaded.params.toml, payload.urdf, report.md there.
    Raises ``DynidError`` with the CLI's message."""
    a = _as_arm(arm)
    items = data if isinstance(data, list) else [data]
    runs = [_data_arg(x, f"data[{k}]", a.dof) for k, x in enumerate(items)]
    twins_in = [] if unloaded is None else (unloaded if isinstance(unloaded, list) else [unloaded])
    twins = [_data_arg(x, f"unloaded[{k}]", a.dof) for k, x in enumerate(twins_in)]
    command = f"dynid.payload({a.name!r}, params={os.fspath(params)!r}, mass={mass!r})"
    scale = None if torque_scale is None else [float(v) for v in torque_scale]
    return _native_payload(
        a,
        os.fspath(params),
        runs,
        twins,
        mass,
        scale,
        cutoff,
        derivative,
        None if out is None else os.fspath(out),
        command,
    )
