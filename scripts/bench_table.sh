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
# outside the repository: skipped with a note when absent), SYMPYBOTICS_ROUNDS (interleaved rounds
# of scripts/bench_sympybotics.py, default 5).
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
elif echo "[bench_table] SymPyBotics anchor ($SB_RUN), ${SYMPYBOTICS_ROUNDS:-5} interleaved rounds ..." >&2 &&
  python3 scripts/bench_sympybotics.py --dynid target/release/dynid --anchor "$SB_RUN" \
    --rounds "${SYMPYBOTICS_ROUNDS:-5}" --markdown docs/sympybotics.md >/dev/null; then
  {
    echo
    echo "### SymPyBotics (optional peer)"
    echo
    echo "SymPyBotics-generated C (symbolic Newton–Euler, straight-line C), from \`../shared/anchors/sympybotics/run.sh\`,"
    echo "which lives outside this repository: SymPyBotics commit 5d4613a, \`cc -O3 -march=native\`, each kernel called"
    echo "out of line through a function pointer, median over repetitions of ns per call cycling through its own"
    echo "1024-sample random pool; the same D-H tables but its own parameter values and base parameters, checked"
    echo "against values stored when the C was generated (\`c\`, Coriolis without gravity, has no counterpart here)."
    echo "Ours: \`dynid bench --arm <arm>\` (one call through the \`Model\` trait). Measured by"
    echo "\`scripts/bench_sympybotics.py\` in interleaved rounds, apart from the table above:"
    echo
    cat docs/sympybotics.md
  } >>docs/bench.md
else
  echo "[bench_table] note: the SymPyBotics anchor failed: no SymPyBotics section (optional)" >&2
fi

cat docs/bench.md
echo "[bench_table] wrote docs/bench.md docs/bench.svg docs/bench.json docs/pinocchio.txt" >&2
