"""dynid.payload (issue 39) returns a typed result equal to the CLI's payload.json. Data: the planar2 arm's torques
from `dynid torque` (the reference Newton–Euler) with and without a 1.5 kg payload lumped into the last link, along
a multi-sine with exact dq/ddq columns — noise-free, so the payload must come back to 1e-6 (the tolerance of the Rust
noise-free test: the fit is exact up to rounding of the normal equations)."""

from __future__ import annotations

import json
import math
import subprocess

import dynid
import numpy as np
import pytest

ARM = "planar2"
# The identified arm (exact) and a payload: 1.5 kg at (0.1, 0.05, 0) m, a small inertia about it.
ARM_P = """[[link]]
m = 2.0
com = [0.3, 0.02, 0.0]
inertia_com = [0.01, 0.0, 0.0, 0.05, 0.0, 0.05]

[[link]]
m = 1.2
com = [0.25, 0.0, 0.01]
inertia_com = [0.008, 0.0, 0.0, 0.03, 0.0, 0.03]
"""
M, C = 1.5, np.array([0.1, 0.05, 0.0])


def loaded_params() -> str:
    m2, c2 = 1.2, np.array([0.25, 0.0, 0.01])
    m = m2 + M
    c = (m2 * c2 + M * C) / m
    i2 = np.diag([0.008, 0.03, 0.03])
    ip = np.diag([0.002, 0.002, 0.002])

    def shift(i, mm, d):
        return i + mm * (d @ d * np.eye(3) - np.outer(d, d))

    ic = shift(i2, m2, c2 - c) + shift(ip, M, C - c)
    six = [ic[0, 0], ic[0, 1], ic[0, 2], ic[1, 1], ic[1, 2], ic[2, 2]]
    first = ARM_P.split("[[link]]")[1]
    return (
        f"[[link]]{first}[[link]]\nm = {m!r}\ncom = [{', '.join(repr(float(v)) for v in c)}]\n"
        f"inertia_com = [{', '.join(repr(float(v)) for v in six)}]\n"
    )


def run(cli, tmp, name, params_text):
    t = np.arange(0, 20, 0.005)
    q, dq, ddq = [], [], []
    for j, (a, w) in enumerate([(0.8, 0.5), (1.1, 0.7)]):
        q.append(a * np.sin(w * 2 * math.pi * 0.3 * t + j))
        dq.append(a * w * 2 * math.pi * 0.3 * np.cos(w * 2 * math.pi * 0.3 * t + j))
        ddq.append(-a * (w * 2 * math.pi * 0.3) ** 2 * np.sin(w * 2 * math.pi * 0.3 * t + j))
    states = np.column_stack([t, *q, *dq, *ddq])
    sp = tmp / f"{name}_states.csv"
    np.savetxt(sp, states, delimiter=",", header="t,q1,q2,dq1,dq2,ddq1,ddq2", comments="", fmt="%.17g")
    pp = tmp / f"{name}.params.toml"
    pp.write_text(params_text)
    tau_csv = tmp / f"{name}_tau.csv"
    subprocess.run(
        [cli, "torque", "--arm", ARM, "--params", str(pp), "--data", str(sp), "--out", str(tau_csv)], check=True
    )
    tau = np.loadtxt(tau_csv, delimiter=",", skiprows=1)[:, 1:]
    out = tmp / f"{name}.csv"
    np.savetxt(
        out,
        np.column_stack([states, tau]),
        delimiter=",",
        comments="",
        fmt="%.17g",
        header="t,q1,q2,dq1,dq2,ddq1,ddq2,tau1,tau2",
    )
    return out


def test_payload_result_is_typed_and_equals_the_cli(dynid_cli, tmp_path):
    loaded = run(dynid_cli, tmp_path, "loaded", loaded_params())
    twin = run(dynid_cli, tmp_path, "twin", ARM_P)
    params = tmp_path / "arm.params.toml"
    params.write_text(ARM_P)
    res = dynid.payload(ARM, params, str(loaded), str(twin), out=tmp_path / "py")
    assert isinstance(res, dynid.PayloadResult)
    assert isinstance(res.com, np.ndarray) and res.com.shape == (3,)
    assert res.inertia.shape == (6,) and res.params.shape == (10,)
    assert res.mass == pytest.approx(M, rel=1e-6)
    assert np.allclose(res.com[:2], C[:2], atol=1e-6)
    assert res.torque_scale is None
    out = tmp_path / "cli"
    cmd = [dynid_cli, "payload", "--arm", ARM, "--params", str(params), "--data", str(loaded), "--unloaded", str(twin)]
    subprocess.run(cmd + ["--out", str(out)], check=True)
    j = json.loads((out / "payload.json").read_text())
    assert j["mass"] == res.mass
    assert j["com"] == list(res.com)
    assert (tmp_path / "py" / "payload.json").is_file()
    with pytest.raises(dynid.DynidError, match="mass"):
        dynid.payload(ARM, params, str(loaded), mass=-1.0)


def test_payload_on_a_table_equals_the_file_and_converts_without_text(dynid_cli, tmp_path):
    """The same run as a file and as a dict of columns: the same estimate, bit for bit. to_dict() is payload.json's
    document built from the Rust values (compared with json.loads of the file written)."""
    loaded = run(dynid_cli, tmp_path, "loaded", loaded_params())
    params = tmp_path / "arm.params.toml"
    params.write_text(ARM_P)
    from_file = dynid.payload(ARM, params, str(loaded), out=tmp_path / "py")
    names = "t,q1,q2,dq1,dq2,ddq1,ddq2,tau1,tau2".split(",")
    table = dict(zip(names, np.loadtxt(loaded, delimiter=",", skiprows=1).T))
    from_table = dynid.payload(ARM, params, table)
    assert from_table.mass == from_file.mass and list(from_table.com) == list(from_file.com)
    assert from_file.to_dict() == json.loads((tmp_path / "py" / "payload.json").read_text())
    assert json.loads(from_file.json) == from_file.to_dict()
    with pytest.raises(dynid.DynidError, match="cutoff: `0` is not a positive number"):
        dynid.payload(ARM, params, table, cutoff=0)
    with pytest.raises(dynid.DynidError, match="torque_scale: 1 factors for an arm with 2 joints"):
        dynid.payload(ARM, params, table, mass=M, torque_scale=[1.0])
