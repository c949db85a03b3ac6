"""Does identification from a designed excitation (`dynid excite`) beat random feasible trajectories?

For each arm, one designed trajectory and K random ones, all of the same family (Fourier series + quintic boundary
term, starting and ending at rest at q0), period, rate and limits, are simulated in MuJoCo as in `eval/suite.py`
(its `simulate`: `mj_inverse` on the URDF `dynid export-urdf` writes, with friction, rotor inertia and offsets,
torque noise and encoder quantisation; Coulomb friction as MuJoCo's `frictionloss`, or with `--coulomb-law sign` as
`level · sign(q̇)` added to the torque — in `mj_inverse` the soft constraint flips about 10 ms before q̇ does at
every reversal, see `suite.COULOMB_LAWS`), identified with `dynid identify` on the true effect set, and judged on
common data that none of them was fitted to:

- **held-out error**: `identify`'s validation error (report.json `error.after.validation.overall`, the least-squares
  model's relative RMS torque error) on one common validation run: a random feasible trajectory of another seed
  (the random candidates' own family, if anything an advantage to them), with noise-free torques and the motion's
  exact q, q̇, q̈ columns, so that the error is the model's and not the noise floor or the accelerations estimated
  from encoder counts (both shared by every candidate);
- **parameter error**: the torque-space error of the identified rigid-body parameters against the truth, on 2000
  random states (q, q̇, q̈ uniform within the limits, no noise): RMS over joints and states of τ_identified − τ_true
  over the RMS of τ_true. τ_true is MuJoCo's `mj_inverse` of the true links without effects; τ_identified is
  `dynid torque` with `identified.params.toml` (the physically consistent estimate `identify` writes, the model a
  user loads) without its `[effects]`. Rigid body only, so that the friction models' own mismatch (MuJoCo's
  frictionloss against identify's smoothed sign) does not hide the parameters' error.

Random trajectories: per joint, harmonic coefficients a_k, b_k ~ N(0, 1), then each joint scaled to the largest
factor that keeps q, q̇, q̈ within its limits less the design's margin (0.5 %) on a 1 ms grid — the same
scaling-into-the-limits the design applies to its candidates — and, where the design checked torques (an arm
imported from a URDF: `effort` through the URDF's inertials), shrunk until the rigid torques stay within the effort
limits as well. So both kinds use every limit as fully as their shape allows; only the shape differs.

Arms: the shipped UR5e- and Panda-like URDFs (designed from the URDF alone: its own limits, acceleration limits
derived from effort and inertia), the generated puma560 and scara, and random modified-D-H arms of 3-6 joints
(`suite.random_table`) with random physical links (`suite.random_params`), under ±2 rad (±0.3 m), 1.5 rad/s
(0.3 m/s), 4 rad/s² (1 m/s²).

    python eval/excitation.py --dynid target/release/dynid --out out/excitation            # the full comparison
    python eval/excitation.py --dynid target/release/dynid --quick --out out/excitation-q  # the test subset

Writes OUT/results.json and OUT/summary.md (the table of docs/excitation.md). Exit 0 when every run worked, 77
without MuJoCo.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import suite  # noqa: E402

REPO = suite.REPO
MARGIN = 0.005
CHECK_HZ = 1000.0
STATES = 2000


# --- arms -------------------------------------------------------------------------------------------------------


def arm_cases(quick: bool) -> list[dict]:
    """The arms compared: shipped URDFs, generated arms and random D-H arms (seeded)."""
    urdfs = [
        {"name": n, "urdf": str(REPO / "data" / "urdf" / f"{n}.urdf"), "seed": 100 + i}
        for i, n in enumerate(["ur5e", "panda"])
    ]
    generated = [{"name": n, "generated": n, "seed": 200 + i} for i, n in enumerate(["puma560", "scara"])]
    random = [{"name": f"random{s}", "random": s, "seed": s} for s in (3, 7, 11)]
    if quick:  # the fastest arms, where a short design already separates the two
        return [generated[0], random[1], random[2]]
    return urdfs + generated + random


def dh_limits(kinds: list[str]) -> list[str]:
    """excite flags for a D-H arm: ±2 rad, 1.5 rad/s, 4 rad/s² (prismatic ±0.3 m, 0.3 m/s, 1 m/s²)."""
    pris = [k == "prismatic" for k in kinds]

    def lst(rev: float, pri: float) -> str:
        return ",".join(repr(pri if p else rev) for p in pris)

    return [
        f"--q-min={lst(-2.0, -0.3)}",
        f"--q-max={lst(2.0, 0.3)}",
        f"--dq-max={lst(1.5, 0.3)}",
        f"--ddq-max={lst(4.0, 1.0)}",
    ]


def prepare(dynid: str, case: dict, work: Path) -> dict:
    """The arm dynid identifies (`arm`), its truth (`params`, `urdf` for MuJoCo), joint kinds and excite's arguments."""
    rng = np.random.default_rng(case["seed"])
    if "urdf" in case:
        subprocess.run(
            [dynid, "import-urdf", case["urdf"], "--out", str(work), "--name", "arm"], check=True, capture_output=True
        )
        arm, params = str(work / "arm.toml"), work / "arm.params.toml"
        kinds = [
            ln.split('"')[1] for ln in (work / "arm.toml").read_text().splitlines() if ln.strip().startswith("kind")
        ]
        excite = ["--arm", case["urdf"]]  # the URDF alone: its limits, effort and inertials
    else:
        if "generated" in case:
            arm, kinds = case["generated"], suite.generated_kinds(case["generated"])
        else:
            table, kinds = suite.random_table(rng, case["name"])
            kinds_keep = min(len(kinds), 6)
            if len(kinds) < 3 or kinds_keep < len(kinds):
                head, *rows = table.split("[[joint]]")
                while len(rows) < 3:  # at least 3 joints: extend with copies of the last row
                    rows.append(rows[-1])
                    kinds.append(kinds[-1])
                rows, kinds = rows[:6], kinds[:6]
                table = "[[joint]]".join([head, *rows])
            (work / "arm.toml").write_text(table)
            arm = str(work / "arm.toml")
        params = work / "truth.params.toml"
        params.write_text(suite.random_params(rng, len(kinds)))
        excite = ["--arm", arm, *dh_limits(kinds)]
    urdf = work / "truth.urdf"
    subprocess.run(
        [dynid, "export-urdf", "--arm", arm, "--params", str(params), "--out", str(urdf)],
        check=True,
        capture_output=True,
    )
    return {"arm": arm, "params": params, "urdf": urdf, "kinds": kinds, "excite": excite, "torque": "urdf" in case}


# --- trajectories -----------------------------------------------------------------------------------------------


def fourier_quintic(period: float, q0: np.ndarray, a: np.ndarray, b: np.ndarray, t: np.ndarray) -> tuple:
    """q, q̇, q̈ (len(t) x n) of the family `dynid excite` designs in (src/trajectory/fourier_quintic.rs): per joint
    q0 + Σ_k a_k/(kw) sin kwt − b_k/(kw) cos kwt, plus the quintic that makes it start and end at rest at q0."""
    n, nh = a.shape
    w = 2 * math.pi / period
    q, dq, ddq = (np.tile(q0 if m == 0 else 0.0 * q0, (len(t), 1)) for m in range(3))
    f0 = np.zeros((3, n))  # harmonics' value, slope, curvature at t = 0 (= at t = T)
    for k in range(1, nh + 1):
        wk = k * w
        s, c = np.sin(wk * t)[:, None], np.cos(wk * t)[:, None]
        ak, bk = a[:, k - 1], b[:, k - 1]
        q += (ak * s - bk * c) / wk
        dq += ak * c + bk * s
        ddq += wk * (-ak * s + bk * c)
        f0 += np.array([-bk / wk, ak, wk * bk])
    # p(0) = -f(0), p'(0) = -f'(0), p''(0) = -f''(0); p, p', p'' equal at 0 and T
    big_t = period
    m = np.zeros((6, 6))
    m[0, 0], m[1, 1], m[2, 2] = 1.0, 1.0, 2.0
    for i in range(1, 6):
        m[3, i] = big_t**i
        m[4, i] = i * big_t ** (i - 1) if i >= 2 else 0.0
        m[5, i] = i * (i - 1) * big_t ** (i - 2) if i >= 3 else 0.0
    for j in range(n):
        c = np.linalg.solve(m, [-f0[0, j], -f0[1, j], -f0[2, j], 0, 0, 0])
        for i in range(6):
            q[:, j] += c[i] * t**i
            if i >= 1:
                dq[:, j] += i * c[i] * t ** (i - 1)
            if i >= 2:
                ddq[:, j] += i * (i - 1) * c[i] * t ** (i - 2)
    return q, dq, ddq


def limits_of(design: dict) -> dict:
    lim = design["limits"]
    get = lambda k: np.array([j[k] for j in lim["joints"]])  # noqa: E731
    tau = [j.get("tau_max") for j in lim["joints"]]
    return {
        "q0": np.array(lim["q0"]),
        "q_min": get("q_min"),
        "q_max": get("q_max"),
        "dq_max": get("dq_max"),
        "ddq_max": get("ddq_max"),
        "tau_max": np.array([np.inf if v is None else v for v in tau]),
    }


def scale_into(lim: dict, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
    """Per joint, the largest factor (≤ 1 not imposed) keeping every signal within its limit less the margin."""
    keep = 1.0 - MARGIN
    d = q - lim["q0"]
    with np.errstate(divide="ignore"):
        r = np.minimum.reduce(
            [
                keep * (lim["q_max"] - lim["q0"]) / np.maximum(d.max(axis=0), 0.0),
                keep * (lim["q0"] - lim["q_min"]) / np.maximum(-d.min(axis=0), 0.0),
                keep * lim["dq_max"] / np.abs(dq).max(axis=0),
                keep * lim["ddq_max"] / np.abs(ddq).max(axis=0),
            ]
        )
    return r


def random_feasible(rng: np.random.Generator, lim: dict, period: float, nh: int, rigid) -> tuple:  # noqa: ANN001
    """A random Fourier + quintic trajectory scaled into the limits on the 1 ms grid (and the effort limits when
    they are finite), with its 1 ms samples."""
    n = len(lim["q0"])
    t = np.arange(0.0, period + 0.5 / CHECK_HZ, 1.0 / CHECK_HZ)
    a, b = rng.normal(0.0, 1.0, (n, nh)), rng.normal(0.0, 1.0, (n, nh))
    q, dq, ddq = fourier_quintic(period, lim["q0"], a, b, t)
    s = scale_into(lim, q, dq, ddq)
    a, b = a * s[:, None], b * s[:, None]
    if np.isfinite(lim["tau_max"]).any():
        for _ in range(60):
            q, dq, ddq = fourier_quintic(period, lim["q0"], a, b, t)
            tau = np.abs(rigid(q, dq, ddq)).max(axis=0)
            if (tau <= (1.0 - MARGIN) * lim["tau_max"]).all():
                break
            a, b = 0.95 * a, 0.95 * b
        else:
            raise RuntimeError("no torque-feasible scaling")
    return a, b


def check(lim: dict, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> float:
    """The largest use of a position, velocity or acceleration limit (1 = at the limit)."""
    d = q - lim["q0"]
    use = np.maximum.reduce(
        [
            d.max(axis=0) / (lim["q_max"] - lim["q0"]),
            -d.min(axis=0) / (lim["q0"] - lim["q_min"]),
            np.abs(dq).max(axis=0) / lim["dq_max"],
            np.abs(ddq).max(axis=0) / lim["ddq_max"],
        ]
    )
    return float(use.max())


# --- one arm ----------------------------------------------------------------------------------------------------


def spec_for(case: dict, kinds: list[str], rng: np.random.Generator, rate: float, coulomb_law: str) -> dict:
    """The suite's case fields for these runs: effects the design's columns model (viscous and Coulomb on every joint,
    rotor inertia (not on joint 1) and offsets on about half), sized below on the validation run; 1 % torque noise,
    18-bit encoders, positions only, no jitter or drops."""
    effects = []
    for j in range(len(kinds)):
        effects.append({"effect": "viscous", "joint": j + 1, "share": float(rng.uniform(0.03, 0.2))})
        effects.append({"effect": "coulomb", "joint": j + 1, "share": float(rng.uniform(0.03, 0.2))})
        for e in ("armature", "offset"):
            # the first joint's rotor inertia is its ZZR1 for every motion: it would bias the rigid-body error
            if rng.random() < 0.5 and not (e == "armature" and j == 0):
                effects.append({"effect": e, "joint": j + 1, "share": float(rng.uniform(0.02, 0.1))})
    return {
        "seed": case["seed"],
        "kinds": kinds,
        "effects": effects,
        "rate": rate,
        "jitter": 0.0,
        "drop": 0.0,
        "encoder_bits": 18,
        "noise": 0.01,
        "velocity_column": False,
        "coulomb_law": coulomb_law,
    }


def exact_states(log: Path, motion: tuple) -> Path:
    """The noise-free validation log rewritten with the motion's exact q, dq, ddq columns (no drops or jitter in these
    specs, so the rows correspond): the held-out error is then the model's, not the shared error of accelerations
    estimated from encoder counts."""
    t, q, dq, ddq = motion
    n = q.shape[1]
    tau = np.loadtxt(log, delimiter=",", skiprows=1)[:, 1 + n :]
    assert tau.shape == q.shape, "the validation log must keep every sample"
    cols = ["t"] + [f"{p}{j + 1}" for p in ("q", "dq", "ddq", "tau") for j in range(n)]
    out = log.with_name("exact.csv")
    np.savetxt(out, np.hstack([t[:, None], q, dq, ddq, tau]), delimiter=",", header=",".join(cols), comments="")
    return out


def identify(dynid: str, arm: str, runs: list[Path], out: Path, effects: str) -> dict:
    """`dynid identify` on two logs of one trajectory, validated on the common run (physical estimate on, so the
    identified model is written as identified.params.toml)."""
    cmd = [dynid, "identify", "--arm", arm, "--data", str(runs[0]), "--data", str(runs[1])]
    cmd += ["--validate", str(runs[2]), "--out", str(out), "--effects", effects]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        return {"failed": p.stderr.strip()[-400:]}
    r = json.loads((out / "report.json").read_text())
    return {"validation": r["error"]["after"]["validation"]["overall"]}


def torque_error(dynid: str, arm: str, params: Path, states: Path, truth: np.ndarray, out: Path) -> float:
    """RMS of τ_identified − τ_true over the RMS of τ_true on the random states, rigid body only: the identified
    model is `params` without its `[effects]`."""
    text = params.read_text()
    rigid = out.with_suffix(".params.toml")
    rigid.write_text(text.split("[effects]")[0])
    subprocess.run(
        [dynid, "torque", "--arm", arm, "--params", str(rigid), "--data", str(states), "--out", str(out)],
        check=True,
        capture_output=True,
    )
    pred = np.loadtxt(out, delimiter=",", skiprows=1)[:, 1:]
    return float(np.sqrt(((pred - truth) ** 2).mean() / (truth**2).mean()))


def run_arm(args: tuple[str, dict, int, Path, float, int, str]) -> dict:
    dynid, case, k_random, root, budget, generations, coulomb_law = args
    import mujoco

    work = root / case["name"]
    work.mkdir(parents=True, exist_ok=True)
    arm = prepare(dynid, case, work)
    period, nh, rate = 10.0, 5, 500.0
    start = time.perf_counter()
    p = subprocess.run(
        [dynid, "excite", *arm["excite"], "--period", str(period), "--harmonics", str(nh), "--rate", str(rate)]
        + ["--generations", str(generations), "--budget-s", str(budget), "--out", str(work / "design")],
        capture_output=True,
        text=True,
    )
    design_s = time.perf_counter() - start
    if p.returncode != 0:
        return {"arm": case["name"], "failed": "excite: " + p.stderr.strip()[-400:]}
    design = json.loads((work / "design" / "excitation.json").read_text())
    lim = limits_of(design)
    if not arm["torque"]:
        lim["tau_max"] = np.full(len(lim["q0"]), np.inf)
    rng = np.random.default_rng(case["seed"] + 17)
    spec = spec_for(case, arm["kinds"], rng, rate, coulomb_law)

    model = suite.load_model(mujoco, arm["urdf"])
    data = mujoco.MjData(model)

    def rigid(q, dq, ddq):  # noqa: ANN001, ANN202
        return suite.inverse(mujoco, model, data, q, dq, ddq)

    def sim(spec: dict, d: Path, runs: list) -> tuple[list[Path], list[dict]]:
        d.mkdir(parents=True, exist_ok=True)
        return suite.simulate(mujoco, spec, arm["urdf"], d, runs=runs)

    t = np.arange(0.0, period + 0.5 / rate, 1.0 / rate)
    # the common validation run and the effects, sized on it once (absolute coefficients for every candidate)
    va, vb = random_feasible(np.random.default_rng(case["seed"] + 99), lim, period, nh, rigid)
    val = (t, *fourier_quintic(period, lim["q0"], va, vb, t))
    sizing = sim(spec, work / "sizing", [val])[1]
    spec["effects"] = sizing
    val_log = exact_states(sim({**spec, "noise": 0.0}, work / "validation", [val])[0][0], val)
    true_arg = ",".join(f"{e['effect']}:{e['joint']}" for e in sizing)
    # random states within the limits and their true torques (noise free)
    n = len(lim["q0"])
    srng = np.random.default_rng(case["seed"] + 5)
    sq = srng.uniform(lim["q_min"], lim["q_max"], (STATES, n))
    sdq = srng.uniform(-lim["dq_max"], lim["dq_max"], (STATES, n))
    sddq = srng.uniform(-lim["ddq_max"], lim["ddq_max"], (STATES, n))
    ts = np.arange(STATES) / 1000.0
    exact = {**spec, "effects": [], "noise": 0.0, "encoder_bits": 52}
    truth_log = sim(exact, work / "truth", [(ts, sq, sdq, sddq)])[0][0]
    truth = np.loadtxt(truth_log, delimiter=",", skiprows=1)[:, 1 + n :]
    states = work / "states.csv"
    cols = ["t"] + [f"{p}{j + 1}" for p in ("q", "dq", "ddq") for j in range(n)]
    np.savetxt(states, np.hstack([ts[:, None], sq, sdq, sddq]), delimiter=",", header=",".join(cols), comments="")

    def evaluate(label: str, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> dict:
        d = work / label
        runs = sim(spec, d, [(t, q, dq, ddq), (t, q, dq, ddq)])[0] + [val_log]
        r = identify(dynid, arm["arm"], runs, d / "id", true_arg)
        if "failed" not in r:
            r["parameter"] = torque_error(
                dynid, arm["arm"], d / "id" / "identified.params.toml", states, truth, d / "pred.csv"
            )
        return r

    g = np.loadtxt(work / "design" / "trajectory.csv", delimiter=",", skiprows=1)
    qd, dqd, ddqd = g[:, 1 : 1 + n], g[:, 1 + n : 1 + 2 * n], g[:, 1 + 2 * n :]
    out = {"arm": case["name"], "dof": n, "design_seconds": design_s, "cond": design["cond"]}
    out["designed"] = {**evaluate("designed", qd, dqd, ddqd), "use": check(lim, qd, dqd, ddqd)}
    out["random"] = []
    for k in range(k_random):
        a, b = random_feasible(np.random.default_rng(case["seed"] * 1000 + k), lim, period, nh, rigid)
        q, dq, ddq = fourier_quintic(period, lim["q0"], a, b, t)
        out["random"].append({**evaluate(f"random{k}", q, dq, ddq), "use": check(lim, q, dq, ddq)})
    return out


# --- summary ----------------------------------------------------------------------------------------------------


def summarise(results: list[dict]) -> tuple[dict, str]:
    rows, wins = [], {"validation": 0, "parameter": 0}
    ok = [r for r in results if "failed" not in r and "failed" not in r["designed"]]
    for r in ok:
        rnd = [x for x in r["random"] if "failed" not in x]
        row = {"arm": r["arm"], "dof": r["dof"], "cond": r["cond"], "random_runs": len(rnd)}
        for key in ("validation", "parameter"):
            med = float(np.median([x[key] for x in rnd])) if rnd else float("nan")
            row[key] = {"designed": r["designed"][key], "random_median": med, "random_best": min(x[key] for x in rnd)}
            wins[key] += r["designed"][key] < med
        rows.append(row)
    s = {"arms": len(results), "compared": len(ok), "designed_beats_random_median": wins, "rows": rows}
    for key in ("validation", "parameter"):
        ratio = [x[key]["designed"] / x[key]["random_median"] for x in rows]
        s[f"{key}_ratio_median"] = float(np.median(ratio)) if ratio else float("nan")
    lines = [
        "| arm | DOF | cond (design) | held-out error, designed | random: median (best) | torque-space parameter"
        " error, designed | random: median (best) |",
        "|---|---|---|---|---|---|---|",
    ]
    for x in rows:
        v, p = x["validation"], x["parameter"]
        lines.append(
            f"| {x['arm']} | {x['dof']} | {x['cond']:.1f} | {100 * v['designed']:.2f} %"
            f" | {100 * v['random_median']:.2f} %"
            f" ({100 * v['random_best']:.2f} %) | {100 * p['designed']:.2f} % | {100 * p['random_median']:.2f} %"
            f" ({100 * p['random_best']:.2f} %) |"
        )
    lines += [
        "",
        f"Designed beats the random median on {wins['validation']} of {len(rows)} arms (held-out error) and"
        f" {wins['parameter']} of {len(rows)} (parameter error); median ratio designed / random median:"
        f" {s['validation_ratio_median']:.3f} (held-out), {s['parameter_ratio_median']:.3f} (parameter).",
    ]
    return s, "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dynid", required=True)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--random", type=int, default=5, help="random trajectories per arm (default 5)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="3 arms, 3 random trajectories, a 40-generation design")
    ap.add_argument(
        "--coulomb-law",
        choices=suite.COULOMB_LAWS,
        default="mujoco",
        help="Coulomb friction as MuJoCo's frictionloss (default) or level·sign(q̇) added to the torque",
    )
    a = ap.parse_args(argv)
    try:
        import mujoco  # noqa: F401
    except ImportError as e:
        print(f"missing: {e} — run scripts/test.sh (it sets up .venv/)", file=sys.stderr)
        return suite.SKIP
    a.out.mkdir(parents=True, exist_ok=True)
    k = 3 if a.quick else a.random
    # quick: the generation count, not the clock, ends the design, so a debug build gives the same numbers
    generations, budget = (40, 600.0) if a.quick else (300, 60.0)
    jobs = [
        (str(Path(a.dynid).resolve()), c, k, a.out.resolve(), budget, generations, a.coulomb_law)
        for c in arm_cases(a.quick)
    ]
    start = time.perf_counter()
    results = []
    with ProcessPoolExecutor(max_workers=a.jobs) as pool:
        for r in pool.map(run_arm, jobs):
            results.append(r)
            if "failed" in r:
                print(f"{r['arm']}: failed: {r['failed']}")
                continue
            d = r["designed"]
            med = np.median([x.get("validation", np.nan) for x in r["random"]])
            print(f"{r['arm']}: designed {d.get('validation', d.get('failed'))}, random median {med}")
    summary, md = summarise(results)
    summary["wall_seconds"] = time.perf_counter() - start
    (a.out / "results.json").write_text(json.dumps(results, indent=1))
    (a.out / "summary.json").write_text(json.dumps(summary, indent=1))
    (a.out / "summary.md").write_text(md)
    print(md)
    print(f"wall time {summary['wall_seconds']:.0f} s")
    failed = sum("failed" in r or "failed" in r["designed"] or any("failed" in x for x in r["random"]) for r in results)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
