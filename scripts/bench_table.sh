#!/usr/bin/env bash
# Regenerates the README benchmark section: Pinocchio's harness and `dynid bench` in the same run,
# then the table (docs/bench.md), the plot (docs/bench.svg) and the raw numbers (docs/bench.json,
# docs/pinocchio.txt).
#
#   scripts/bench_table.sh
#
# Needs: cargo; python3 with venv + network for the first Pinocchio run (it installs `pin` from
# PyPI into ~/.cache/pinbench and compiles its benchmark once, ~2-3 min on 2 cores; later runs
# take seconds). Timings are only comparable on a quiet machine: the load average is recorded in
# the table. Knobs: PINOCCHIO_RUN (harness path), BENCH_CPU (pin both to one CPU with taskset,
# passed to the harness as PINBENCH_CPU), DYNID_BENCH_ARGS (extra `dynid bench` options).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
PIN_RUN="${PINOCCHIO_RUN:-$ROOT/../shared/anchors/pinocchio/run.sh}"
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
"$PIN_RUN" >docs/pinocchio.txt
echo "[bench_table] dynid bench ..." >&2
# shellcheck disable=SC2086
"${TASKSET[@]}" target/release/dynid bench --json \
  --pinocchio docs/pinocchio.txt --markdown docs/bench.md --svg docs/bench.svg \
  ${DYNID_BENCH_ARGS:-} >docs/bench.json

cat docs/bench.md
echo "[bench_table] wrote docs/bench.md docs/bench.svg docs/bench.json docs/pinocchio.txt" >&2
