"""The binding's contract beyond the numbers: input errors, reference-dynamics arms, URDF import, pickling."""

from __future__ import annotations

import pickle
from pathlib import Path

import dynid
import numpy as np
import pinocchio as pin
import pytest
from conftest import REPO, pin_q, plausible_params, random_states, rel_err


@pytest.fixture(scope="module")
def puma():
    return dynid.Arm("puma560")


def test_wrong_shapes_and_dtypes_are_value_errors_that_say_the_expected_shape(puma):
    q = np.zeros((5, 6))
    with pytest.raises(ValueError, match=r"q: expected shape \(6,\) for one sample or \(N, 6\)"):
        puma.base_regressor(np.zeros((5, 7)), q, q)
    with pytest.raises(ValueError, match=r"q: expected shape .* got \(2, 5, 6\)"):
        puma.base_regressor(np.zeros((2, 5, 6)), q, q)
    with pytest.raises(ValueError, match=r"ddq: expected shape \(5, 6\) like q, got \(4, 6\)"):
        puma.base_regressor(q, q, np.zeros((4, 6)))
    with pytest.raises(ValueError, match=r"dq: expected shape \(6,\) like q, got \(5, 6\)"):
        puma.bias(q[0], q, np.zeros(60))
    with pytest.raises(ValueError, match=r"q: expected a float64 numpy array, got a numpy array of dtype int64"):
        puma.regressor(np.zeros((5, 6), dtype=np.int64), q, q)
    with pytest.raises(ValueError, match="float32"):
        puma.gravity(np.zeros(6, dtype=np.float32), np.zeros(60))
    with pytest.raises(ValueError, match=r"params: expected shape \(60,\)"):
        puma.inverse_dynamics(q, q, q, np.zeros(36))
    with pytest.raises(ValueError, match="got a str"):
        puma.mass_matrix("0,0,0,0,0,0", np.zeros(60))


def test_unknown_arm_and_bad_files_are_dynid_errors_with_the_cli_messages(tmp_path):
    with pytest.raises(dynid.DynidError, match="unknown arm `puma650` — did you mean `puma560`"):
        dynid.Arm("puma650")
    assert issubclass(dynid.DynidError, ValueError)
    bad = tmp_path / "bad.toml"
    bad.write_text((REPO / "arms" / "planar2.toml").read_text().replace("alpha = 0.0", "alpha = 'x'", 1))
    with pytest.raises(dynid.DynidError, match=r"bad.toml:\d+: joint\[1\]\.alpha"):
        dynid.Arm.from_dh(bad)
    with pytest.raises(dynid.DynidError, match="cannot read the D-H table"):
        dynid.Arm.from_dh(tmp_path / "missing.toml")
    with pytest.raises(dynid.DynidError, match="nope.urdf"):
        dynid.import_urdf(tmp_path / "nope.urdf")


def test_an_arm_from_a_dh_file_runs_the_reference_dynamics_and_agrees_with_the_kernels(tmp_path, puma):
    path = tmp_path / "my_puma.toml"
    path.write_text(puma.dh_toml.replace('name = "puma560"', 'name = "my_puma"'))
    ref = dynid.Arm.from_dh(path)
    assert not ref.generated and "reference dynamics (not compiled in)" in repr(ref)
    assert "generated kernels" in repr(puma)
    assert (ref.dof, ref.nb) == (puma.dof, puma.nb)
    rng = np.random.default_rng(3)
    q, dq, ddq = random_states(puma, 9, rng)
    p = plausible_params(6, rng)
    for kernel in ("mass_matrix", "gravity"):
        assert rel_err(getattr(ref, kernel)(q, p), getattr(puma, kernel)(q, p)) < 1e-12
    assert rel_err(ref.bias(q, dq, p), puma.bias(q, dq, p)) < 1e-12
    assert rel_err(ref.inverse_dynamics(q, dq, ddq, p), puma.inverse_dynamics(q, dq, ddq, p)) < 1e-12
    assert rel_err(ref.regressor(q, dq, ddq), puma.regressor(q, dq, ddq)) < 1e-12
    # The numerical base spans the same torques: Yb_ref · θ_ref = Y · p.
    tau = ref.base_regressor(q, dq, ddq) @ ref.base_params(p)
    assert rel_err(tau, puma.inverse_dynamics(q, dq, ddq, p)) < 1e-9
    assert len(ref.base_param_names) == ref.nb == len(ref.base_param_exprs)


def test_from_urdf_and_import_urdf_give_the_torques_of_the_exported_arm(tmp_path):
    panda = dynid.Arm("panda")
    rng = np.random.default_rng(5)
    p = plausible_params(panda.dof, rng)
    urdf = tmp_path / "panda_export.urdf"
    urdf.write_text(panda.to_urdf(p))
    imported = dynid.import_urdf(urdf)
    arm = dynid.Arm.from_urdf(urdf)
    assert imported.arm == arm and "from_urdf" in repr(arm) and not arm.generated
    assert imported.params.shape == (70,) and len(imported.chain) == 7
    q, dq, ddq = random_states(panda, 12, rng)
    tau = arm.inverse_dynamics(q, dq, ddq, imported.params)
    assert rel_err(tau, panda.inverse_dynamics(q, dq, ddq, p)) < 1e-9
    model = pin.buildModelFromXML(urdf.read_text())
    data = model.createData()
    for k in range(len(q)):
        assert rel_err(tau[k], pin.rnea(model, data, pin_q(model, q[k]), dq[k], ddq[k])) < 1e-9
    dh, params = imported.write(tmp_path / "out")
    assert dynid.Arm.from_dh(dh) == arm
    assert np.array_equal(dynid.read_params(params, 7), imported.params)


def test_arms_pickle_and_compute_the_same_after(tmp_path, puma):
    path = tmp_path / "my_arm.toml"
    path.write_text((REPO / "arms" / "scara.toml").read_text().replace('name = "scara"', 'name = "my_arm"'))
    rng = np.random.default_rng(8)
    for arm in (puma, dynid.Arm.from_dh(path)):
        back = pickle.loads(pickle.dumps(arm))
        assert back == arm and repr(back) == repr(arm)
        q, dq, ddq = random_states(arm, 5, rng)
        assert np.array_equal(back.base_regressor(q, dq, ddq), arm.base_regressor(q, dq, ddq))
        assert hash(back) == hash(arm) and len({arm, back}) == 1  # equal arms hash alike
    path.unlink()  # a pickled D-H arm carries its table, not a path
    assert pickle.loads(pickle.dumps(dynid.Arm.from_dh(Path(__file__).parents[2] / "arms" / "planar2.toml"))).dof == 2
    # Arms key dicts: a generated arm and the same table's reference dynamics are different keys.
    by_arm = {puma: "generated", dynid.Arm.from_dh(REPO / "arms" / "puma560.toml"): "table"}
    assert len(by_arm) == 2 and by_arm[dynid.Arm("puma560")] == "generated"


def test_names_and_expressions_are_attributes(puma):
    planar = dynid.Arm("planar2")
    assert planar.base_param_names[:2] == ["ZZR1", "MXR1"]
    assert "M2" in planar.base_param_exprs[0]
    assert puma.param_names[:10] == ["XX1", "XY1", "XZ1", "YY1", "YZ1", "ZZ1", "MX1", "MY1", "MZ1", "M1"]
    assert puma.base_map.shape == (puma.nb, puma.np) and dynid.Arm.kernels()[1] == "base_regressor"


def test_out_writes_into_a_preallocated_array_and_is_checked(puma):
    rng = np.random.default_rng(11)
    q, dq, ddq = random_states(puma, 9, rng)
    want = puma.base_regressor(q, dq, ddq)
    y = np.full((9, 6, puma.nb), np.nan)
    assert puma.base_regressor(q, dq, ddq, out=y) is y and np.array_equal(y, want)
    with pytest.raises(
        ValueError, match=r"out: expected a C-contiguous, writeable float64 array of shape \(9, 6, 36\)"
    ):
        puma.base_regressor(q, dq, ddq, out=np.zeros((9, 6, 35)))
    with pytest.raises(ValueError, match="out: expected"):
        puma.base_regressor(q, dq, ddq, out=np.zeros((9, 6, puma.nb), dtype=np.float32))
    with pytest.raises(ValueError, match="also one of the inputs"):
        puma.gravity(q, np.zeros(60), out=q)


def test_the_stubs_name_what_the_module_has():
    import ast

    stub = ast.parse((Path(dynid.__file__).parent / "__init__.pyi").read_text())
    top = {n.name for n in stub.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
    assert top - {"_Array"} <= set(dir(dynid)), top - set(dir(dynid))
    assert set(dynid.__all__) - {"__version__"} <= top
    arm = next(n for n in stub.body if isinstance(n, ast.ClassDef) and n.name == "Arm")
    methods = {n.name for n in arm.body if isinstance(n, ast.FunctionDef)} - {"__init__"}
    assert methods <= set(dir(dynid.Arm)), methods - set(dir(dynid.Arm))
    assert {k for k in dir(dynid.Arm) if not k.startswith("_")} <= methods


@pytest.mark.parametrize("name, samples", [("puma560", 5001), ("panda", 3501)])
def test_a_large_reused_output_written_with_streaming_stores_holds_the_same_numbers(name, samples):
    """Past 8 MB a reused out= is written with non-temporal stores (src/batch.rs): same values, every sample.
    PUMA: 5001 · 6 · 36 · 8 bytes = 8.6 MB, rows of an even length (16-byte pairs); Panda: 3501 · 7 · 43 · 8 bytes
    = 8.4 MB, odd rows (value by value); both with a scalar tail (samples mod 4 = 1)."""
    arm = dynid.Arm(name)
    rng = np.random.default_rng(12)
    q, dq, ddq = random_states(arm, samples, rng)
    want = arm.base_regressor(q, dq, ddq)
    assert want.nbytes > 8 << 20
    y = np.full_like(want, np.nan)
    for threads in (1, None):
        y[:] = np.nan
        arm.base_regressor(q, dq, ddq, out=y, threads=threads)
        assert np.array_equal(y, want)


def test_large_outputs_come_from_reused_buffers_never_shared_with_a_live_array():
    """Outputs of >= 8 MB are Rust buffers lent to numpy and taken back when the array dies (src/pool.rs): the next
    call of that size writes into the same memory — every value, whatever was left there — and no buffer is lent twice
    while an array or a view of it lives."""
    arm = dynid.Arm("puma560")
    q, dq, ddq = random_states(arm, 5003, np.random.default_rng(13))
    want = arm.base_regressor(q, dq, ddq)
    assert want.nbytes >= 8 << 20 and want.flags.writeable
    a = arm.base_regressor(q, dq, ddq)
    assert not np.shares_memory(a, want) and np.array_equal(a, want)
    a[:] = np.nan
    address = a.ctypes.data
    del a
    b = arm.base_regressor(q, dq, ddq)
    assert b.ctypes.data == address and np.array_equal(b, want)
    view = b[17]
    del b
    c = arm.base_regressor(q, dq, ddq)
    assert not np.shares_memory(view, c) and np.array_equal(view, want[17]) and np.array_equal(c, want)
