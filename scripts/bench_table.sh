#!/usr/bin/env bash
# Regenerates the README benchmark section: Pinocchio's harness and `dynid bench` in the same run,
# then the table (docs/bench.md), the plot (docs/bench.svg) and the raw numbers (docs/bench.json,
# docs/pinocchio.txt).
#
#   scripts/bench_table.sh
#
# Needs: cargo, a C++17 compiler; python3 with venv + network for the first Pinocchio run (the
# harness benches/peers/pinocchio/run.sh installs the pinned `pin` wheel from PyPI into
# ~/.cache/dynid-peers and compiles its benchmark once, ~2-3 min on 2 cores; later runs take
# seconds). It times Pinocchio on dynid's own models and input pool (`dynid bench-models`) and
# stops before timing if its torques differ from dynid's. Timings are only comparable on a quiet
# machine: the load average is recorded in the table. Knobs: PINOCCHIO_RUN (another harness
# printing `pinocchio,<model>,<algo>,<ns>` lines), BENCH_CPU (pin both to one CPU with taskset,
# passed to the harness as PINBENCH_CPU), DYNID_BENCH_ARGS (extra `dynid bench` options),
# SYMPYBOTICS_RUN (the optional SymPyBotics anchor; default ../shared/anchors/sympybotics/run.sh,
# outside the repository: skipped with a note when absent).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
PIN_RUN="${PINOCCHIO_RUN:-$ROOT/benches/peers/pinocchio/run.sh}"
[[ -x "$PIN_RUN" ]] || { echo "bench_table: Pinocchio harness not found at $PIN_RUN (set PINOCCHIO_RUN)" >&2; exit 2; }
mkdir -p docs

echo "[bench_table] load average: $(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo unknown)" >&2
cargo build --release --quiet --bin dynid

TASKSET=()
if [[ -n "${BENCH_CPU:-}" ]]; then
  TASKSET=(taskset -c "$BENCH_CPU")
  export PINBENCH_CPU="$BENCH_CPU"
fi

echo "[bench_table] Pinocchio harness ($PIN_RUN) ..." >&2
DYNID="$ROOT/target/release/dynid" "$PIN_RUN" >docs/pinocchio.txt
echo "[bench_table] dynid bench ..." >&2
# shellcheck disable=SC2086
"${TASKSET[@]}" target/release/dynid bench --json \
  --pinocchio docs/pinocchio.txt --markdown docs/bench.md --svg docs/bench.svg \
  ${DYNID_BENCH_ARGS:-} >docs/bench.json

# Optional second peer: SymPyBotics-generated C, when the shared anchors sit next to the
# repository (they are not part of it). Skipped with a note otherwise or if it fails.
SB_RUN="${SYMPYBOTICS_RUN:-$ROOT/../shared/anchors/sympybotics/run.sh}"
if [[ ! -x "$SB_RUN" ]]; then
  echo "[bench_table] note: $SB_RUN not found: no SymPyBotics section (optional)" >&2
elif echo "[bench_table] SymPyBotics anchor ($SB_RUN) ..." >&2 &&
  SYMBENCH_CPU="${BENCH_CPU:-}" "$SB_RUN" >docs/sympybotics.txt; then
  python3 - docs/bench.json docs/sympybotics.txt >>docs/bench.md <<'PY'
import json, sys
ours = {(k["arm"], k["kernel"]): k["generated_ns"] for k in json.load(open(sys.argv[1]))["kernels"]}
kernel = {"tau": "inverse_dynamics", "M": "mass_matrix", "g": "gravity", "H": "regressor", "Hb": "base_regressor"}
rows = []
for line in open(sys.argv[2]):
    f = line.strip().split(",")
    if len(f) == 4 and f[0] == "sympybotics" and f[2] in kernel and (f[1], kernel[f[2]]) in ours:
        g = ours[(f[1], kernel[f[2]])]
        rows.append(f"| {f[1]} | {kernel[f[2]]} | {g:.1f} | {float(f[3]):.1f} | {float(f[3]) / g:.1f}× |")
if rows:
    print("\n### SymPyBotics (optional peer)\n")
    print("SymPyBotics-generated C (symbolic Newton–Euler, straight-line C), timed in the same run right after "
          "`dynid bench` by `../shared/anchors/sympybotics/run.sh`, which lives outside this repository: "
          "SymPyBotics commit 5d4613a, `cc -O3 -march=native`, kernels called out of line, median over repetitions "
          "of ns per call cycling through its own 1024-sample random pool; the same D-H tables but its own "
          "parameter values and its own choice of base parameters, checked against values stored when the C "
          "was generated. `c` (Coriolis without gravity) has no counterpart here.\n")
    print("| arm | kernel | generated | SymPyBotics C | SymPyBotics / generated |\n|---|---|---:|---:|---:|")
    print("\n".join(rows))
PY
else
  echo "[bench_table] note: the SymPyBotics anchor failed: no SymPyBotics section (optional)" >&2
fi

cat docs/bench.md
echo "[bench_table] wrote docs/bench.md docs/bench.svg docs/bench.json docs/pinocchio.txt" >&2
