"""Payload identification and drive-gain calibration against an independent simulator (issue 39).

`dynid payload` estimates what the flange carries from a loaded run and its unloaded twin, given the arm `dynid
identify` identified; with the payload's mass known it calibrates one torque scale per joint. Here both are scored
against MuJoCo (`mj_inverse`), with the suite's pieces (`eval/suite.py`: URDF loading, joint effects as MuJoCo
damping/frictionloss/armature, excitations, noise, encoders, dropped samples, timing jitter):

- arms: the generated puma560 and panda, the UR5e-, UR10e- and Panda-like URDFs of data/urdf/ (their own inertials
  are the truth) and random modified-D-H tables of 6-7 joints with random links (written by `dynid export-urdf`).
  Planar arms are left out: a payload on them has only its in-plane centre of mass and one inertia identifiable;
- effects: viscous, Coulomb, rotor inertia on random joints, sized as the suite sizes them (1-30 % of the joint's
  rigid torque RMS); log rate, jitter, drops, encoder bits, torque noise, velocity column, excitation kind and
  duration are the suite's draws for the same seed (`case_spec`);
- per case: three unloaded runs -> `dynid identify` -> identified.params.toml; a payload (0.5-5 kg, centre of mass
  uniform in a 15 cm ball about the last link's origin, a solid box of 2-20 cm sides at a random orientation) fixed
  to the last body in MuJoCo; a loaded run and its unloaded twin (the same motion, the twin's log starting 0.2-0.8 s
  earlier) -> `dynid payload`; scored in the frame payload.json reports (the last D-H frame: the transform from the
  URDF link's frame is measured by probing both simulators with point masses, see `dh_frame`);
- drive gains: the logged torque of that pair and of a second, held-out pair (another motion) is divided by random
  per-joint scales s_j in [0.8, 1.2]; `dynid payload --mass M` on the first pair calibrates them, `dynid payload
  --torque-scale` on the held-out pair must then give the mass.

    python eval/payload.py --dynid target/release/dynid --cases 40 --jobs 2 --out out/payload   # the full run
    python eval/payload.py --dynid target/release/dynid --cases 6 --quick --out out/payload6    # the test subset
    python eval/payload.py --dynid target/release/dynid --cases 3 --exact --out out/exact       # noise-free check

`--exact`: noise-free logs with dq and ddq columns, the true arm instead of an identified one and a twin shifted by a
whole number of samples: every error must be at rounding level (it checks the frames and the scoring, not the
method). Writes OUT/cases.json and OUT/summary.json / summary.md. Exit status 0 when every case ran, 77 without
MuJoCo.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import suite  # noqa: E402

REPO = suite.REPO
SKIP = 77
ARMS = ["puma560", "panda", "ur5e.urdf", "ur10e.urdf", "panda.urdf", "random"]
FRICTION = ["viscous", "coulomb", "armature"]


# --- case generation --------------------------------------------------------------------------------------------


def random_arm(rng: np.random.Generator, seed: int) -> tuple[str, str | None, list[str]]:
    """(arm, D-H table text or None, joint kinds): a generated arm, a data/urdf/ file or a random 6-7-joint table."""
    arm = str(rng.choice(ARMS))
    if arm.endswith(".urdf"):
        return str(REPO / "data" / "urdf" / arm), None, []  # kinds from MuJoCo
    if arm != "random":
        return arm, None, suite.generated_kinds(arm)
    while True:
        table, kinds = suite.random_table(rng, f"random{seed}")
        if len(kinds) >= 6:
            return f"random{seed}", table, kinds


def random_payload(rng: np.random.Generator) -> dict:
    """Mass 0.5-5 kg, centre of mass uniform in a 15 cm ball, inertia of a solid box of 2-20 cm sides, rotated."""
    m = float(rng.uniform(0.5, 5.0))
    d = rng.normal(size=3)
    c = d / np.linalg.norm(d) * 0.15 * rng.random() ** (1 / 3)
    a, b, h = rng.uniform(0.02, 0.2, 3)
    moments = m / 12 * np.array([b * b + h * h, a * a + h * h, a * a + b * b])
    r, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    inertia = r @ np.diag(moments) @ r.T
    return {"mass": m, "com": c.tolist(), "inertia": inertia.tolist()}


def random_effects(rng: np.random.Generator, n: int) -> list[dict]:
    """Friction as the suite draws its effects (each joint and kind with probability 0.18, none in 1 case of 5)."""
    effects = []
    if rng.random() > 0.2:
        for j in range(n):
            for e in FRICTION:
                if rng.random() < 0.18:
                    effects.append({"effect": e, "joint": j + 1, "share": float(rng.uniform(0.01, 0.30))})
    return effects


def case_spec(seed: int, quick: bool = False, exact: bool = False) -> dict:
    """Everything random about a case, from its seed. The log's conditions are the suite's for the same seed;
    `quick`: at most 500 Hz and 15 s runs; `exact`: noise-free (see the module doc)."""
    base = suite.case_spec(seed)
    spec = {k: base[k] for k in ("rate", "jitter", "drop", "encoder_bits", "noise", "velocity_column")}
    spec.update({k: base[k] for k in ("excitation", "duration")})
    rng = np.random.default_rng(seed + 39_000_039)
    spec["seed"], spec["quick"], spec["exact"] = seed, quick, exact
    spec["arm"], spec["table"], spec["kinds"] = random_arm(rng, seed)
    spec["payload"] = random_payload(rng)
    spec["scale"] = rng.uniform(0.8, 1.2, 7).tolist()  # the first n are the case's
    spec["shift"] = [float(x) for x in rng.uniform(0.2, 0.8, 2)]
    spec["motions"] = [int(x) for x in rng.integers(0, 2**31, 5)]  # identify x3, loaded pair, held-out pair
    spec["link_seed"] = int(rng.integers(0, 2**31))
    spec["effect_seed"] = int(rng.integers(0, 2**31))
    if quick:
        spec["rate"] = min(spec["rate"], 500.0)
        spec["duration"] = 15.0
    if exact:
        spec.update(jitter=0.0, drop=0.0, noise=0.0, encoder_bits=60, velocity_column=True)
    return spec


# --- simulation (MuJoCo) ----------------------------------------------------------------------------------------


def with_payload(mujoco, urdf: Path, body: str, payload: dict):  # noqa: ANN001, ANN201
    """The URDF's MuJoCo model with the payload as a body welded to `body` (frame = the body's URDF link frame)."""
    spec = mujoco.MjSpec.from_file(str(urdf))
    p = spec.body(body).add_body()
    p.name = "payload"
    p.pos = payload["com"]
    p.mass = payload["mass"]
    p.ipos = [0.0, 0.0, 0.0]
    i = np.array(payload["inertia"])
    p.fullinertia = [i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]]
    p.explicitinertial = True
    model = spec.compile()
    model.jnt_limited[:] = 0
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    return model


def motion(spec: dict, k: int, kinds: list[str], t: np.ndarray) -> tuple[np.ndarray, ...]:
    """Motion `k` of the case (the suite's excitation from its own seed) at times t ≤ duration + 1 s: the same
    function of t for any grid, so a twin evaluates it on a shifted one (the point-to-point moves are drawn up
    to that fixed horizon, whatever the grid)."""
    horizon = np.append(t, spec["duration"] + 1.0)
    q, dq, ddq = suite.excitation(np.random.default_rng(spec["motions"][k]), kinds, horizon, spec["excitation"])
    return q[:-1], dq[:-1], ddq[:-1]


def write_exact(t: np.ndarray, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, tau: np.ndarray, path: Path) -> Path:
    n = q.shape[1]
    cols = ["t"] + [f"{b}{j + 1}" for b in ("q", "dq", "ddq", "tau") for j in range(n)]
    table = np.hstack([t[:, None], q, dq, ddq, tau])
    np.savetxt(path, table, delimiter=",", header=",".join(cols), comments="", fmt="%.17g")
    return path


def log(spec: dict, rng: np.random.Generator, run: tuple, tau: np.ndarray, path: Path) -> Path:
    """The logged file of `run` = (t_log, q, dq, ddq) with torque `tau`."""
    t, q, dq, ddq = run
    if spec["exact"]:
        return write_exact(t, q, dq, ddq, tau, path)
    return suite.write_log(spec, rng, t, q, dq, tau, path)


def simulate(mujoco, spec: dict, urdf: Path, work: Path) -> dict:  # noqa: ANN001
    """Every log of the case: identify runs, the loaded pair and the held-out pair (plain and with the drive
    scales), and the effects with their coefficients."""
    unloaded = suite.load_model(mujoco, urdf)
    n = unloaded.nv
    body = unloaded.body(unloaded.jnt_bodyid[n - 1]).name
    loaded = with_payload(mujoco, urdf, body, spec["payload"])
    assert abs(loaded.body_subtreemass[0] - unloaded.body_subtreemass[0] - spec["payload"]["mass"]) < 1e-9
    du, dl = mujoco.MjData(unloaded), mujoco.MjData(loaded)
    rng = np.random.default_rng(spec["seed"] + 1_000_003)
    dt = 1.0 / spec["rate"]
    kinds = spec["kinds"]
    t = np.arange(0.0, spec["duration"], dt)
    ident = [(t, *motion(spec, k, kinds, t)) for k in range(3)]
    q, dq, ddq = ident[0][1:]
    rms = np.sqrt((suite.inverse(mujoco, unloaded, du, q, dq, ddq) ** 2).mean(axis=0)) + 1e-9
    effects, _, _ = suite.set_effects(
        unloaded, random_effects(np.random.default_rng(spec["effect_seed"]), n), *ident[0][1:], rms
    )
    suite.set_effects(loaded, effects, q, dq, ddq, rms)
    out: dict = {"effects": effects, "body": body, "identify": [], "pairs": []}
    for k, run in enumerate(ident):
        tau = suite.inverse(mujoco, unloaded, du, *run[1:])
        out["identify"].append(log(spec, rng, run, tau, work / f"id{k + 1}.csv"))
    scale = np.array(spec["scale"][:n])
    for p in range(2):
        shift = spec["shift"][p]
        if spec["exact"]:
            shift = round(shift / dt) * dt
        lrun = (t, *motion(spec, 3 + p, kinds, t))
        t_twin = np.arange(0.0, spec["duration"] + 1.0, dt)
        urun = (t_twin, *motion(spec, 3 + p, kinds, t_twin - shift))
        tau_l = suite.inverse(mujoco, loaded, dl, *lrun[1:])
        tau_u = suite.inverse(mujoco, unloaded, du, *urun[1:])
        files = {}
        for tag, s in (("", 1.0), ("_scaled", scale)):
            files["loaded" + tag] = log(spec, rng, lrun, tau_l / s, work / f"loaded{p + 1}{tag}.csv")
            files["twin" + tag] = log(spec, rng, urun, tau_u / s, work / f"twin{p + 1}{tag}.csv")
        out["pairs"].append({"shift": shift, **files})
    return out


# --- the frame payload.json reports -----------------------------------------------------------------------------


def dynid_torque(dynid: str, arm: str, params: str, states: np.ndarray, work: Path) -> np.ndarray:
    n = states.shape[1] // 3
    data, pfile, out = work / "probe_states.csv", work / "probe.params.toml", work / "probe_tau.csv"
    cols = ["t"] + [f"{b}{i}" for b in ("q", "dq", "ddq") for i in range(1, n + 1)]
    table = np.hstack([np.arange(len(states))[:, None] * 0.01, states])
    np.savetxt(data, table, delimiter=",", header=",".join(cols), comments="", fmt="%.17g")
    pfile.write_text(params)
    cmd = [dynid, "torque", "--arm", arm, "--params", str(pfile), "--data", str(data), "--out", str(out)]
    run(cmd)
    return np.loadtxt(out, delimiter=",", skiprows=1)[:, 1:]


def point_mass_params(n: int, com: np.ndarray) -> str:
    """Massless links but the last, a 1 kg point at `com` (its D-H frame)."""
    com = [float(x) for x in com]
    link = "[[link]]\nm = 0.0\ncom = [0.0, 0.0, 0.0]\ninertia_com = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\n"
    last = (
        f"[[link]]\nm = 1.0\ncom = [{com[0]!r}, {com[1]!r}, {com[2]!r}]\ninertia_com = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\n"
    )
    return link * (n - 1) + last


def dh_frame(mujoco, dynid: str, arm: str, model, body: str, work: Path) -> tuple[np.ndarray, np.ndarray, float]:  # noqa: ANN001
    """(R, p, residual): a point r of the last body's URDF frame is R·r + p in the last D-H frame. Measured by
    probing: the holding torque of a 1 kg point at r (MuJoCo: -Jᵀ·m·g at 24 random poses) is matched by dynid's
    torque of a 1 kg point on the last D-H link, which is affine in the point's coordinates (4 `dynid torque` runs);
    the point that matches it is solved for, for 4 probes, and the rigid transform fitted through them (Kabsch).
    `residual`: the worst probe misfit (m), ~1e-12 when the two simulators agree on the geometry."""
    n = model.nv
    rng = np.random.default_rng(0)
    q = rng.uniform(-math.pi, math.pi, (24, n))
    states = np.hstack([q, np.zeros((24, 2 * n))])
    basis = [
        dynid_torque(dynid, arm, point_mass_params(n, c), states, work) for c in np.vstack([np.zeros(3), np.eye(3)])
    ]
    a = np.stack([(b - basis[0]).ravel() for b in basis[1:]], axis=1)  # d tau / d com
    data = mujoco.MjData(model)
    bid = model.body(body).id
    probes = 0.1 * np.vstack([np.zeros(3), np.eye(3)])
    mapped = []
    worst = 0.0
    for r in probes:
        tau = np.zeros((24, n))
        for k in range(24):
            data.qpos[:] = q[k]
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            point = data.xpos[bid] + data.xmat[bid].reshape(3, 3) @ r
            jacp = np.zeros((3, model.nv))
            mujoco.mj_jac(model, data, jacp, None, point, bid)
            tau[k] = -jacp.T @ model.opt.gravity
        x, *_ = np.linalg.lstsq(a, (tau - basis[0]).ravel(), rcond=None)
        fit = basis[0].ravel() + a @ x
        worst = max(worst, float(np.abs(fit - tau.ravel()).max() / max(np.abs(tau).max(), 1e-12)))
        mapped.append(x)
    mapped = np.array(mapped)
    pc, mc = probes.mean(axis=0), mapped.mean(axis=0)
    u, _, vt = np.linalg.svd((mapped - mc).T @ (probes - pc))
    d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    rot = u @ d @ vt
    p = mc - rot @ pc
    residual = float(np.abs(mapped - (probes @ rot.T + p)).max())
    return rot, p, max(residual, worst)


def truth_in_dh(payload: dict, rot: np.ndarray, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    c = rot @ np.array(payload["com"]) + p
    return payload["mass"], c, rot @ np.array(payload["inertia"]) @ rot.T


# --- running and scoring ----------------------------------------------------------------------------------------


def run(cmd: list[str]) -> subprocess.CompletedProcess:
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd[:2])} failed: {p.stderr.strip()[-400:]}")
    return p


def payload(dynid: str, arm: str, params: Path, loaded: Path, twin: Path, out: Path, extra: list[str]) -> dict:
    cmd = [dynid, "payload", "--arm", arm, "--params", str(params), "--data", str(loaded), "--unloaded", str(twin)]
    run([*cmd, "--out", str(out), *extra])
    return json.loads((out / "payload.json").read_text())


def score_estimate(est: dict, truth: tuple) -> dict:
    """Errors of one payload.json against the truth (mass, COM, inertia in the last D-H frame) and σ coverage."""
    m, c, inertia = truth
    com, sc = np.array(est["com"]), np.array(est["sigma"]["com"])
    e = [[est["inertia"][0], est["inertia"][1], est["inertia"][2]]]
    e += [
        [est["inertia"][1], est["inertia"][3], est["inertia"][4]],
        [est["inertia"][2], est["inertia"][4], est["inertia"][5]],
    ]
    top = float(np.linalg.eigvalsh(inertia).max())
    return {
        "mass": est["mass"],
        "mass_error": abs(est["mass"] - m) / m,
        "mass_z": abs(est["mass"] - m) / max(est["sigma"]["mass"], 1e-300),
        "com_error": float(np.linalg.norm(com - c)),
        "com_z": float(np.max(np.abs(com - c) / np.maximum(sc, 1e-300))),
        "inertia_error": float(np.abs(np.array(e) - inertia).max() / top),
        "warnings": est["warnings"],
    }


def arm_files(dynid: str, spec: dict, work: Path) -> tuple[str, Path, str | None]:
    """(the --arm argument, the truth URDF MuJoCo loads, the true params file for `--exact`)."""
    if spec["arm"].endswith(".urdf"):
        imported = work / "imported"
        run([dynid, "import-urdf", spec["arm"], "--name", "truth", "--out", str(imported)])
        return spec["arm"], Path(spec["arm"]), str(imported / "truth.params.toml")
    arm = spec["arm"]
    if spec["table"] is not None:
        (work / "arm.toml").write_text(spec["table"])
        arm = str(work / "arm.toml")
    n = len(spec["kinds"])
    (work / "truth.params.toml").write_text(suite.random_params(np.random.default_rng(spec["link_seed"]), n))
    urdf = work / "truth.urdf"
    run([dynid, "export-urdf", "--arm", arm, "--params", str(work / "truth.params.toml"), "--out", str(urdf)])
    return arm, urdf, str(work / "truth.params.toml")


def run_case(args: tuple[str, int, str, bool, bool]) -> dict:
    dynid, seed, keep, quick, exact = args
    import mujoco

    spec = case_spec(seed, quick, exact)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(keep) / f"case{seed}" if keep else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        arm, urdf, true_params = arm_files(dynid, spec, work)
        if not spec["kinds"]:
            model = suite.load_model(mujoco, urdf)
            spec["kinds"] = ["revolute" if t == mujoco.mjtJoint.mjJNT_HINGE else "prismatic" for t in model.jnt_type]
        logs = simulate(mujoco, spec, urdf, work)
        n = len(spec["kinds"])
        rot, p, residual = dh_frame(mujoco, dynid, arm, suite.load_model(mujoco, urdf), logs["body"], work)
        truth = truth_in_dh(spec["payload"], rot, p)
        out: dict = {"frame_residual": residual, "effects": logs["effects"]}
        try:
            if exact:
                params = Path(true_params)
            else:
                ident = [
                    *(x for f in logs["identify"][:2] for x in ("--data", str(f))),
                    "--validate",
                    str(logs["identify"][2]),
                ]
                run([dynid, "identify", "--arm", arm, *ident, "--out", str(work / "id")])
                params = work / "id" / "identified.params.toml"
            pair, held = logs["pairs"]
            est = payload(dynid, arm, params, pair["loaded"], pair["twin"], work / "payload", [])
            out["payload"] = score_estimate(est, truth)
            out["payload"]["shift_error"] = abs(est["runs"][0]["alignment"]["shift_s"] - pair["shift"])
            m = f"{spec['payload']['mass']!r}"
            cal = payload(dynid, arm, params, pair["loaded_scaled"], pair["twin_scaled"], work / "gains", ["--mass", m])
            s_true = np.array(spec["scale"][:n])
            s_est = np.array(cal["torque_scale"])
            calibrated = [j for j in range(n) if j + 1 not in cal["uncalibrated_joints"]]
            scales = ",".join(repr(float(v)) for v in s_est)
            held_est = payload(
                dynid,
                arm,
                params,
                held["loaded_scaled"],
                held["twin_scaled"],
                work / "held",
                ["--torque-scale", scales],
            )
            out["gains"] = {
                "scale_error": [float(abs(s_est[j] / s_true[j] - 1)) for j in range(n)],
                "calibrated": [j + 1 for j in calibrated],
                "held_out_mass_error": abs(held_est["mass"] - truth[0]) / truth[0],
            }
        except RuntimeError as e:
            out["failed"] = str(e)
    out["seconds"] = time.perf_counter() - start
    spec_out = {k: v for k, v in spec.items() if k not in ("table",)}
    return {"spec": spec_out, **out}


def quantiles(x: list[float]) -> dict:
    a = np.array(x) if x else np.array([np.nan])
    return {"median": float(np.median(a)), "p90": float(np.percentile(a, 90)), "max": float(a.max())}


def score(cases: list[dict]) -> dict:
    ok = [c for c in cases if "failed" not in c]
    pay = [c["payload"] for c in ok]
    gains = [c["gains"] for c in ok]
    cal_err = [e for g in gains for j, e in enumerate(g["scale_error"]) if j + 1 in g["calibrated"]]
    n_joints = sum(len(g["scale_error"]) for g in gains)
    return {
        "cases": len(cases),
        "failed": len(cases) - len(ok),
        "frame_residual_max": max((c["frame_residual"] for c in cases), default=float("nan")),
        "mass_error": quantiles([p["mass_error"] for p in pay]),
        "com_error_m": quantiles([p["com_error"] for p in pay]),
        "inertia_error": quantiles([p["inertia_error"] for p in pay]),
        "mass_covered_1sigma": float(np.mean([p["mass_z"] <= 1 for p in pay])) if pay else float("nan"),
        "mass_covered_2sigma": float(np.mean([p["mass_z"] <= 2 for p in pay])) if pay else float("nan"),
        "com_covered_1sigma": float(np.mean([p["com_z"] <= 1 for p in pay])) if pay else float("nan"),
        "com_covered_2sigma": float(np.mean([p["com_z"] <= 2 for p in pay])) if pay else float("nan"),
        "cases_with_warnings": sum(bool(p["warnings"]) for p in pay),
        "scale_error_calibrated": quantiles(cal_err),
        "scales_within_1pct": float(np.mean([e <= 0.01 for e in cal_err])) if cal_err else float("nan"),
        "joints_calibrated": f"{len(cal_err)}/{n_joints}",
        "held_out_mass_error": quantiles([g["held_out_mass_error"] for g in gains]),
        "held_out_within_1pct": float(np.mean([g["held_out_mass_error"] <= 0.01 for g in gains]))
        if gains
        else float("nan"),
        "seconds_per_case": quantiles([c["seconds"] for c in cases]),
    }


def markdown(s: dict, a: argparse.Namespace) -> str:
    def pct(q: dict) -> str:
        return f"{100 * q['median']:.3g} % (90th percentile {100 * q['p90']:.3g} %, worst {100 * q['max']:.3g} %)"

    def mm(q: dict) -> str:
        return f"{1e3 * q['median']:.3g} mm (90th percentile {1e3 * q['p90']:.3g}, worst {1e3 * q['max']:.3g})"

    def cover(key: str) -> str:
        return f"{s[key + '_1sigma']:.2f} of cases at 1σ, {s[key + '_2sigma']:.2f} at 2σ"

    mode = ", quick" if a.quick else ", exact" if a.exact else ""
    secs = s["seconds_per_case"]
    lines = [
        f"Cases {s['cases']} (seeds {a.first_seed}..{a.first_seed + a.cases - 1}{mode}), failed {s['failed']};"
        f" frame probe residual ≤ {s['frame_residual_max']:.1e}.",
        "",
        "| measure | value | issue 39's bar |",
        "|---|---|---|",
        f"| mass error | {pct(s['mass_error'])} | median ≤ 2 % |",
        f"| COM error | {mm(s['com_error_m'])} | median ≤ 5 mm |",
        f"| σ covers the mass error | {cover('mass_covered')} | ≥ 0.9 |",
        f"| σ covers the COM error (worst axis) | {cover('com_covered')} | ≥ 0.9 |",
        f"| inertia error (worst entry / largest principal moment) | {pct(s['inertia_error'])} | — |",
        f"| cases with an excitation warning | {s['cases_with_warnings']} | — |",
        f"| drive gains, calibrated joints: scale error | {pct(s['scale_error_calibrated'])};"
        f" {s['scales_within_1pct']:.2f} within 1 % ({s['joints_calibrated']} joints calibrated) | ≤ 1 % |",
        f"| held-out run, calibrated gains: mass error | {pct(s['held_out_mass_error'])};"
        f" {s['held_out_within_1pct']:.2f} within 1 % | ≤ 1 % |",
        f"| run time per case | median {secs['median']:.0f} s, worst {secs['max']:.0f} s | |",
    ]
    return "\n".join(lines) + "\n"


def progress(c: dict) -> str:
    """One line per finished case."""
    p, g = c.get("payload"), c.get("gains")
    worst = max((g["scale_error"][j - 1] for j in g["calibrated"]), default=0.0) if g else 0.0
    status = c.get("failed") or (
        f"mass {100 * p['mass_error']:.3g} % ({p['mass_z']:.1f}σ), COM {1e3 * p['com_error']:.3g} mm"
        f" ({p['com_z']:.1f}σ), gains {100 * worst:.3g} %"
        f" (calibrated {g['calibrated']}), held-out mass {100 * g['held_out_mass_error']:.3g} %"
    )
    return f"case {c['spec']['seed']}: {Path(c['spec']['arm']).name}, {c['spec']['payload']['mass']:.2f} kg: {status}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dynid", required=True)
    ap.add_argument("--cases", type=int, default=40)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--keep", action="store_true", help="keep every case's logs and outputs under OUT/")
    ap.add_argument("--quick", action="store_true", help="the test command's subset: <= 500 Hz, 15 s runs")
    ap.add_argument("--exact", action="store_true", help="noise-free logs and the true arm: errors at rounding level")
    a = ap.parse_args(argv)
    try:
        import mujoco  # noqa: F401
    except ImportError as e:
        print(f"missing: {e} — run scripts/test.sh (it sets up .venv/)", file=sys.stderr)
        return SKIP
    a.out.mkdir(parents=True, exist_ok=True)
    keep = str(a.out.resolve()) if a.keep else ""
    jobs = [
        (str(Path(a.dynid).resolve()), s, keep, a.quick, a.exact) for s in range(a.first_seed, a.first_seed + a.cases)
    ]
    start = time.perf_counter()
    cases = []
    with ProcessPoolExecutor(max_workers=a.jobs) as pool:
        for c in pool.map(run_case, jobs):
            cases.append(c)
            print(progress(c), flush=True)
            (a.out / "cases.json").write_text(json.dumps(cases, indent=1, default=str))  # so far
    summary = score(cases)
    summary["wall_seconds"] = time.perf_counter() - start
    (a.out / "summary.json").write_text(json.dumps(summary, indent=1))
    md = markdown(summary, a)
    (a.out / "summary.md").write_text(md)
    print(md)
    print(f"wall time {summary['wall_seconds']:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
