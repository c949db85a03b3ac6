"""Do two `dynid` binaries write the same files? The check behind a refactor that must not change results.

Runs every command of a fixed list (the paper, identify on the shared simulated set, a DFKI leave-one-out, the
TIAGo URDF round trip, excite, simulate on a generated arm and on a URDF, torque, payload, import/export
URDF) with each binary into its own directory, then compares every file byte for byte. Only what is meant to
differ between two runs of the same binary is masked first: wall-clock times (`Run time: 12.3 s`, a timing
table's seconds, the solver's `Newton steps (68 ms)`, the search's `stopped by …, 4.0 s`, the paper command's
`in 35.3 s;`, JSON keys `timings`/`runtime_s`/`seconds`/`elapsed_s`) and nothing else; `--show-masked` prints
what was masked.

    python scripts/compare_outputs.py --before /tmp/old/dynid --after target/release/dynid [--only paper,identify]

Exit 0 when every file is identical after masking, 1 with the differing files listed (and a unified diff of the
first lines of each text file), 2 on bad arguments.
"""

from __future__ import annotations

import argparse
import difflib
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SIM = "data/sim/planar2_paper_friction"
DFKI = "data/real/dfki_double_pendulum"
TIAGO = "data/real/tiago_figaroh"
UR5E = "data/urdf/ur5e.urdf"
CTC = ["--controller", "ctc", "--kp", ",".join(["400"] * 6), "--kd", ",".join(["40"] * 6)]

# name -> list of argument lists, run in order in one directory (later commands may read earlier outputs).
CASES: dict[str, list[list[str]]] = {
    "paper": [["paper", "--out", "paper"]],
    "identify": [
        ["identify", "--arm", f"{SIM}/arm.toml", "--data", f"{SIM}/excite_noisy.csv.gz"]
        + ["--validate", f"{SIM}/validate_noisy.csv.gz", "--out", "sim"],
    ],
    "dfki": [
        ["identify", "--arm", f"{DFKI}/arm.toml"]
        + [a for r in ["00", "01", "02", "04", "05", "11", "12", "13"] for a in ("--data", f"{DFKI}/run_{r}.csv.gz")]
        + ["--leave-one-out", "--out", "dfki"],
    ],
    "tiago": [
        ["identify", "--arm", f"{TIAGO}/tiago.urdf", "--data", f"{TIAGO}/fit.csv.gz"]
        + ["--validate", f"{TIAGO}/holdout.csv.gz", "--out", "tiago"],
        ["import-urdf", f"{TIAGO}/tiago.urdf", "--out", "tiago_arm"],
    ],
    "ur5e": [
        ["excite", "--arm", UR5E, "--limits", "data/urdf/ur5e.limits.toml", "--generations", "60", "--out", "ex"],
        ["simulate", "--arm", UR5E, "--params", "docs/examples/ur5e_friction.params.toml"]
        + ["--trajectory", "ex/excitation.json", *CTC, "--tau-noise", "0.01", "--positions-only"]
        + ["--log-every", "2", "--out", "log.csv"],
        ["identify", "--arm", UR5E, "--data", "log.csv", "--out", "id"],
        ["simulate", "--arm", UR5E, "--params", "docs/examples/ur5e_payload.params.toml"]
        + ["--trajectory", "ex/excitation.json", *CTC, "--tau-noise", "0.01", "--positions-only"]
        + ["--log-every", "2", "--seed", "3", "--out", "loaded.csv"],
        ["payload", "--arm", UR5E, "--params", "id/identified.params.toml", "--data", "loaded.csv"]
        + ["--unloaded", "log.csv", "--out", "payload"],
        ["torque", "--arm", UR5E, "--params", "id/identified.params.toml", "--data", "log.csv", "--out", "tau.csv"],
    ],
    "planar2": [
        ["excite", "--arm", "planar2", "--q-min", "-2,-2", "--q-max", "2,2", "--dq-max", "2,2", "--ddq-max", "5,5"]
        + ["--generations", "60", "--out", "ex2"],
        ["simulate", "--arm", "planar2", "--params", "docs/examples/planar2_spring.params.toml"]
        + ["--trajectory", "ex2/excitation.json", "--out", "clean.csv"],
        ["export-urdf", "--arm", "planar2", "--params", "docs/examples/planar2_spring.params.toml", "--out", "p2.urdf"],
    ],
}

TIME_LINE = re.compile(r"(Run time: )[0-9.]+( s)")
SOLVER_TIME = re.compile(r"(Newton steps \(|stopped by [a-z ]+, )[0-9.]+( ms\)| s)")
WROTE_IN = re.compile(r"(\) in )[0-9.]+( s;)")  # the paper command's closing line: "wrote paper (…) in 35.3 s;"
TIME_JSON_KEYS = {"timings", "runtime_s", "seconds", "elapsed_s"}


def mask_json(value):
    if isinstance(value, dict):
        return {k: ("<time>" if k in TIME_JSON_KEYS else mask_json(v)) for k, v in value.items()}
    if isinstance(value, list):
        return [mask_json(v) for v in value]
    return value


def mask(path: Path, data: bytes) -> bytes:
    """The file's bytes with wall-clock times replaced (see the module doc)."""
    if path.suffix == ".json":
        try:
            return json.dumps(mask_json(json.loads(data)), indent=1, sort_keys=True).encode()
        except ValueError:
            return data
    if path.suffix == ".exit":
        return WROTE_IN.sub(r"\1<time>\2", data.decode()).encode()
    if path.suffix == ".md":
        text = SOLVER_TIME.sub(r"\1<time>\2", TIME_LINE.sub(r"\1<time>\2", data.decode()))
        # The paper report's timing table: `| stage | seconds |` rows under "## Run time".
        out, in_timing = [], False
        for line in text.splitlines(keepends=True):
            if line.startswith("#"):
                in_timing = "run time" in line.lower() or "timing" in line.lower()
            if in_timing and line.startswith("|"):
                line = re.sub(r"\|\s*[0-9.]+\s*\|\s*$", "| <time> |", line)
            out.append(line)
        return "".join(out).encode()
    return data


def run_case(binary: Path, name: str, workdir: Path) -> list[str]:
    """Runs one case's commands in `workdir` (the repository's data linked in); returns the failures."""
    for entry in ("data", "docs", "arms"):
        link = workdir / entry
        if not link.exists():
            link.symlink_to(REPO / entry)
    failures = []
    for args in CASES[name]:
        r = subprocess.run([str(binary), *args], cwd=workdir, capture_output=True, text=True)
        (workdir / f"_{args[0]}_{len(failures)}.exit").write_text(f"{r.returncode}\n{r.stdout}")
        if r.returncode != 0:
            failures.append(f"{name}: `dynid {' '.join(args)}` exited {r.returncode}: {r.stderr.strip()[-400:]}")
    return failures


def files(root: Path) -> dict[str, Path]:
    """Every file a case wrote under `root` (the linked-in repository folders not followed)."""
    out = {}
    for dirpath, _dirs, names in os.walk(root):  # os.walk does not follow symlinked folders
        for n in names:
            p = Path(dirpath) / n
            if not p.is_symlink():
                out[str(p.relative_to(root))] = p
    return dict(sorted(out.items()))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", type=Path, required=True, help="the reference dynid binary")
    ap.add_argument("--after", type=Path, required=True, help="the dynid binary under test")
    ap.add_argument("--only", default="", help=f"comma list of cases (default all: {','.join(CASES)})")
    ap.add_argument("--keep", type=Path, help="write both output trees here instead of a temporary directory")
    ap.add_argument("--show-masked", action="store_true", help="print every masked difference")
    args = ap.parse_args()
    names = [n for n in args.only.split(",") if n] or list(CASES)
    for n in names:
        if n not in CASES:
            print(f"error: --only: unknown case `{n}` — known: {', '.join(CASES)}", file=sys.stderr)
            return 2
    for b in (args.before, args.after):
        if not b.is_file():
            print(f"error: {b}: no such binary — build it (cargo build --release) or fix the path", file=sys.stderr)
            return 2
    base = args.keep or Path(tempfile.mkdtemp(prefix="dynid-compare-"))
    differing, failed, compared = [], [], 0
    for name in names:
        roots = {}
        for side, binary in (("before", args.before), ("after", args.after)):
            root = base / side / name
            root.mkdir(parents=True, exist_ok=True)
            failed += [f"{side}: {f}" for f in run_case(binary.resolve(), name, root)]
            roots[side] = files(root)
        for rel in sorted(set(roots["before"]) | set(roots["after"])):
            a, b = roots["before"].get(rel), roots["after"].get(rel)
            if a is None or b is None:
                differing.append(f"{name}/{rel}: only {'after' if a is None else 'before'}")
                continue
            compared += 1
            da, db = a.read_bytes(), b.read_bytes()
            ma, mb = mask(a, da), mask(b, db)
            if ma != mb:
                differing.append(f"{name}/{rel}")
                if b"\0" not in ma[:4096]:
                    diff = difflib.unified_diff(
                        ma.decode(errors="replace").splitlines(), mb.decode(errors="replace").splitlines(), lineterm=""
                    )
                    print("\n".join(list(diff)[:20]))
            elif da != db and args.show_masked:
                print(f"masked: {name}/{rel}")
        print(f"{name}: {len(roots['after'])} files", flush=True)
    for f in failed:
        print(f"FAILED {f}")
    for d in differing:
        print(f"DIFFERS {d}")
    print(f"{compared} files compared, {len(differing)} differ, {len(failed)} commands failed (outputs in {base})")
    return 1 if differing or failed else 0


if __name__ == "__main__":
    sys.exit(main())
