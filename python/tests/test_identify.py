"""dynid.identify on arrays and DataFrames gives the CLI's result on the same files (report.json compared number by
number), and its errors are the CLI's messages."""

from __future__ import annotations

import json
import math
import pickle
import subprocess
import warnings

import dynid
import numpy as np
import pandas as pd
import pytest
from conftest import REPO

SET = REPO / "data" / "sim" / "planar2_paper_friction"
# Keys whose values name the inputs (file paths vs. "data (DataFrame)") or the command line, not results.
NAMES = {"command", "file", "source"}


def same(a, b, path="report"):
    """Every number of the CLI's report.json equals the Python result's, exactly: the same code runs on the same
    f64 values (the CSV text the CLI reads parses to the values pandas reads with round_trip precision)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), f"{path}: keys differ"
        for k in a:
            if k not in NAMES:
                same(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), f"{path}: lengths differ"
        for i, (x, y) in enumerate(zip(a, b)):
            same(x, y, f"{path}[{i}]")
    elif isinstance(a, float) and math.isnan(a):
        assert isinstance(b, float) and math.isnan(b), f"{path}: {a} vs {b}"
    else:
        assert a == b, f"{path}: CLI {a!r} vs Python {b!r}"


@pytest.fixture(scope="module")
def cli_report(dynid_cli, tmp_path_factory):
    out = tmp_path_factory.mktemp("cli")
    cmd = [dynid_cli, "identify", "--arm", str(SET / "arm.toml"), "--data", str(SET / "excite_noisy.csv.gz")]
    subprocess.run(cmd + ["--validate", str(SET / "validate_noisy.csv.gz"), "--out", str(out)], check=True)
    return json.loads((out / "report.json").read_text())


def test_identify_on_a_dataframe_and_an_array_equals_the_cli_on_the_files(cli_report, tmp_path):
    train = pd.read_csv(SET / "excite_noisy.csv.gz", float_precision="round_trip")
    train = train[["tau2", "q2", "t", "tau1", "q1"]]  # any column order, as in a CSV
    val = pd.read_csv(SET / "validate_noisy.csv.gz", float_precision="round_trip")
    val_array = val[["t", "q1", "q2", "tau1", "tau2"]].to_numpy()  # a bare array: t, q, tau in this order
    result = dynid.identify(dynid.Arm.from_dh(SET / "arm.toml"), train, validate=val_array, out=tmp_path / "py")
    same(cli_report, result.report)
    same(cli_report, json.loads((tmp_path / "py" / "report.json").read_text()))
    assert [e["name"] for e in result.effects_found] == [
        f"{e['effect']}{e['joint']}" for e in cli_report["effects_found"]
    ]
    assert {"viscous1", "coulomb1"} <= {e["name"] for e in result.effects_found}  # the set's truth
    assert all("rel_std_percent" in p for p in result.parameters)
    assert result.errors["after"]["validation"]["overall"] < result.errors["before"]["validation"]["overall"]
    assert result.report_dir == tmp_path / "py" and (tmp_path / "py" / "report.md").is_file()
    back = pickle.loads(pickle.dumps(result))
    assert back == result and "effects found" in repr(result)


def test_identify_on_paths_equals_the_cli(cli_report):
    result = dynid.identify(str(SET / "arm.toml"), SET / "excite_noisy.csv.gz", SET / "validate_noisy.csv.gz")
    same(cli_report, result.report)
    assert result.report_dir is None and result.files == []


def test_bad_data_is_a_dynid_error_with_the_row_and_column():
    train = pd.read_csv(SET / "excite_noisy.csv.gz").iloc[:500].copy()
    train.loc[7, "q2"] = np.nan
    with pytest.raises(dynid.DynidError, match=r"data \(DataFrame\):9: q2: .*NaN"):
        dynid.identify("planar2", train)
    with pytest.raises(dynid.DynidError, match=r"unknown column `tau_1`"):
        dynid.identify("planar2", train.rename(columns={"tau1": "tau_1"}))
    with pytest.raises(ValueError, match="a 4-column array for a 2-joint arm"):
        dynid.identify("planar2", np.zeros((100, 4)))
    with pytest.raises(dynid.DynidError, match="effects: "):
        dynid.identify("planar2", SET / "excite_noisy.csv.gz", effects="viscus")


def test_what_the_data_cannot_identify_is_in_the_result():
    """Joint 1 of a 2-DOF arm never moves: ZZR1 and one of its gravity pair are held at 0 (result.fixed) and the
    warnings say so; torques from the arm's own inverse dynamics (physical links, 1 % noise)."""
    arm = dynid.Arm("planar2")
    t = np.arange(0.0, 20.0, 0.002)
    q = np.column_stack([np.full_like(t, 0.5), np.sin(0.9 * t) + 0.3 * np.sin(2.3 * t)])
    dq = np.column_stack([np.zeros_like(t), 0.9 * np.cos(0.9 * t) + 0.69 * np.cos(2.3 * t)])
    ddq = np.column_stack([np.zeros_like(t), -0.81 * np.sin(0.9 * t) - 1.587 * np.sin(2.3 * t)])
    p = np.zeros(arm.np)
    p[[0, 3, 5, 6, 9]] = [0.2, 0.3, 0.3, 0.5, 2.0]  # link 1: XX, YY, ZZ, MX, M
    p[[10, 13, 15, 16, 19]] = [0.05, 0.15, 0.15, 0.3, 1.0]  # link 2
    tau = arm.inverse_dynamics(q, dq, ddq, p)
    tau += 0.01 * tau.std(axis=0) * np.random.default_rng(3).standard_normal(tau.shape)
    data = {"t": t, "q1": q[:, 0], "q2": q[:, 1], "tau1": tau[:, 0], "tau2": tau[:, 1]}
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        r = dynid.identify(arm, data)
    assert any("cannot identify `ZZR1`" in str(w.message) for w in said), [str(w.message) for w in said]
    assert any(str(w.message).startswith("joint 1 barely moves") for w in said)
    assert r.fixed[0] == "ZZR1" and len(r.fixed) == 2, r.fixed
    assert all(p["value"] == 0.0 for p in r.parameters if p["name"] in r.fixed)
    assert isinstance(r.undetermined, list)


def typed(a, b, path="report"):
    """a == b with the same Python types throughout (an int stays an int, a float a float), NaN equal to NaN."""
    assert type(a) is type(b), f"{path}: {type(a).__name__} vs {type(b).__name__}"
    if isinstance(a, dict):
        assert a.keys() == b.keys(), f"{path}: keys differ"
        for k in a:
            typed(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), f"{path}: lengths differ"
        for i, (x, y) in enumerate(zip(a, b)):
            typed(x, y, f"{path}[{i}]")
    elif isinstance(a, float) and math.isnan(a):
        assert math.isnan(b), f"{path}: {a} vs {b}"
    else:
        assert a == b, f"{path}: {a!r} vs {b!r}"


def test_the_report_object_is_what_json_loads_makes_of_report_json(tmp_path):
    """The report reaches Python as objects built from Rust values, no text in between: it must still be exactly
    what `json.loads` makes of the report.json the same call writes, types included."""
    data = pd.read_csv(SET / "excite_noisy.csv.gz", float_precision="round_trip").iloc[:4000]
    result = dynid.identify("planar2", data, effects="viscous", cutoff=8.0, out=tmp_path)
    typed(json.loads((tmp_path / "report.json").read_text()), result.report)
    assert isinstance(result.report["theta"][0]["value"], float)


def test_a_fixed_coulomb_width_is_the_scans_own_trial():
    """Oracle: the width scan's trial at a fraction refits the same model at that width, so fixing the width at the
    fraction the scan kept gives the same fit and errors (and no scan in the report)."""
    data = pd.read_csv(SET / "excite_noisy.csv.gz", float_precision="round_trip").iloc[:4000]
    scanned = dynid.identify("planar2", data, effects="viscous,coulomb", cutoff=8.0, smoothing="1,states")
    width = scanned.report["coulomb_width"]
    assert [t["fraction"] for t in width["trials"]] == [0.003, 0.01, 0.03]
    fixed = dynid.identify(
        "planar2",
        data,
        effects="viscous,coulomb",
        cutoff=8.0,
        smoothing="1,states",
        coulomb_width=width["chosen_fraction"],
    )
    assert fixed.report["coulomb_width"] is None
    a, b = scanned.report["error"]["after"]["train"], fixed.report["error"]["after"]["train"]
    assert a["overall"] == pytest.approx(b["overall"], rel=1e-9)
    assert [t["value"] for t in scanned.report["theta"]] == pytest.approx(
        [t["value"] for t in fixed.report["theta"]], rel=1e-9
    )


def test_torque_scale_multiplies_an_arrays_torque():
    """Oracle: halving the logged torque and asking for torque_scale=[2, 2] is the unscaled run, number for number
    (both are exact in binary floating point)."""
    data = pd.read_csv(SET / "excite_noisy.csv.gz", float_precision="round_trip").iloc[:4000]
    half = data.copy()
    half[["tau1", "tau2"]] = data[["tau1", "tau2"]] / 2
    plain = dynid.identify("planar2", data, effects="viscous", cutoff=8.0)
    scaled = dynid.identify("planar2", half, effects="viscous", cutoff=8.0, torque_scale=[2.0, 2.0])
    same(plain.report, scaled.report)
    with pytest.raises(dynid.DynidError, match="torque_scale: 3 factors for an arm with 2 joints"):
        dynid.identify("planar2", half, torque_scale=[2.0, 2.0, 2.0])


def test_bad_arrays_and_options_get_the_cli_checks_with_pythons_names():
    t = np.arange(0.0, 1.0, 0.01)
    cols = {"t": t, "q1": np.sin(t), "q2": np.cos(t), "tau1": t, "tau2": t}
    rows = np.arange(len(t))
    inf = dict(cols, tau2=np.where(rows >= 51, np.inf, t))  # row 51: line 53 of the CSV it stands for
    with pytest.raises(dynid.DynidError, match=r"data \(dict\):53: tau2: `inf` is not a finite number"):
        dynid.identify("planar2", inf)
    back = dict(cols, t=np.where(rows == 10, 0.05, t))
    with pytest.raises(dynid.DynidError, match=r"data \(dict\):12: t: t = 0.05 does not increase"):
        dynid.identify("planar2", back)
    with pytest.raises(dynid.DynidError, match="cutoff: `-1` is not a positive number of Hz or `auto`"):
        dynid.identify("planar2", cols, cutoff=-1)
    with pytest.raises(dynid.DynidError, match="cutoff: `fast` is not a positive number"):
        dynid.identify("planar2", cols, cutoff="fast")
    with pytest.raises(dynid.DynidError, match=r"coulomb_width: `2` is not `auto` or a fraction in \(0, 1\]"):
        dynid.identify("planar2", cols, coulomb_width=2)
    with pytest.raises(dynid.DynidError, match="derivative: `spline` is not an estimator"):
        dynid.identify("planar2", cols, derivative="spline")
    with pytest.raises(dynid.DynidError, match=r"data \(dict\): topic and joints are for ROS 2 bags"):
        dynid.identify("planar2", cols, topic="/joint_states")
    with pytest.raises(dynid.DynidError, match="data: no training data"):
        dynid.identify("planar2", [])
