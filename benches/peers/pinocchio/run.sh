#!/usr/bin/env bash
# Pinocchio (C++, header-only) on the models and inputs of `dynid bench`; see README.md.
#
#   benches/peers/pinocchio/run.sh                 # every arm `dynid bench` measures
#   benches/peers/pinocchio/run.sh --arm puma560   # one arm (passed to `dynid bench-models`)
#
# Prints `#` comments, a table and `pinocchio,<arm>,<algo>,<median_ns>` lines (the input of
# `dynid bench --pinocchio FILE`). Exits non-zero, before timing, if Pinocchio's model is not
# dynid's (self-check). First run: creates a venv with the pinned wheels (network) and compiles
# bench.cpp (~2 min on 2 cores); later runs reuse both and take a few seconds.
#
# Knobs (all optional):
#   PEERS_CACHE      venv, binaries, model dump   [${XDG_CACHE_HOME:-$HOME/.cache}/dynid-peers]
#   PEERS_PYTHON     python that creates the venv [python3]
#   CXX              C++ compiler                 [g++]
#   DYNID            dynid binary                 [target/release/dynid, rebuilt with cargo]
#   PINBENCH_CPU     pin the timing run to this CPU with taskset (set by scripts/bench_table.sh)
#   PEERS_TARGET_MS, PEERS_REPS   override dynid's repetition length / count
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../../.." && pwd)"
CACHE="${PEERS_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/dynid-peers}"
PY="${PEERS_PYTHON:-python3}"
CXX="${CXX:-g++}"
# The pinned wheels: `pin` ships Pinocchio and Boost headers under site-packages/cmeel.prefix/,
# `cmeel-eigen` the Eigen headers (pin does not depend on it for its own binaries).
WHEELS=(pin==4.1.0 cmeel-eigen==3.4.1)
OPT=(-O3 -march=native -DNDEBUG)
# Pinocchio's exported compile definitions (its CMake target pinocchio::pinocchio_headers).
PIN_DEFS=(-DBOOST_MPL_LIMIT_LIST_SIZE=30 -DBOOST_MPL_LIMIT_VECTOR_SIZE=30
  -DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS -DBOOST_FUSION_INVOKE_MAX_ARITY=12)

log() { echo "[peers/pinocchio] $*" >&2; }
die() {
  echo "[peers/pinocchio] error: $*" >&2
  exit 1
}
mkdir -p "$CACHE"

# 1. The venv with the pinned wheels (created once; recreated when the pins change).
command -v "$PY" >/dev/null || die "python '$PY' not found"
PYTAG="$("$PY" -c 'import sys; print("cp%d%d" % sys.version_info[:2])')"
VENV="$CACHE/venv-$PYTAG"
if [[ "$(cat "$VENV/.ready" 2>/dev/null)" != "${WHEELS[*]}" ]]; then
  log "creating $VENV with ${WHEELS[*]} (needs the network once)"
  rm -rf "$VENV"
  "$PY" -m venv "$VENV" || die "$PY -m venv failed (Debian/Ubuntu: apt-get install python3-venv)"
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check "${WHEELS[@]}" ||
    die "pip install ${WHEELS[*]} failed"
  echo "${WHEELS[*]}" >"$VENV/.ready"
fi
PREFIX="$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')/cmeel.prefix"
for f in include/pinocchio/config.hpp include/boost/version.hpp include/eigen3/Eigen/Core; do
  [[ -e "$PREFIX/$f" ]] || die "$PREFIX/$f is missing: the wheel layout changed?"
done

# 2. The binary, compiled once per source + flags + compiler + wheels + CPU (-march=native).
command -v "$CXX" >/dev/null || die "no C++ compiler '$CXX' (set CXX)"
CXX_VERSION="$("$CXX" --version | head -1)"
FLAGS=(-std=c++17 "${OPT[@]}" "${PIN_DEFS[@]}")
CPU_FLAGS="$(grep -m1 '^flags' /proc/cpuinfo 2>/dev/null || true)"
KEY="$({
  cat "$HERE/bench.cpp"
  echo "${FLAGS[*]}|$CXX_VERSION|${WHEELS[*]}|$PREFIX|$CPU_FLAGS"
} | sha256sum | cut -c1-16)"
BIN="$CACHE/bench-$KEY"
if [[ ! -x "$BIN" ]]; then
  log "compiling bench.cpp with $CXX ${OPT[*]} (header-only Pinocchio: ~2 min on 2 cores) ..."
  start=$SECONDS
  if ! "$CXX" "${FLAGS[@]}" -DPEERS_CXX="\"$CXX_VERSION\"" -DPEERS_FLAGS="\"${OPT[*]}\"" \
    -isystem "$PREFIX/include" -isystem "$PREFIX/include/eigen3" \
    "$HERE/bench.cpp" -o "$BIN.tmp.$$" >"$BIN.log" 2>&1; then
    rm -f "$BIN.tmp.$$"
    grep -E 'error' "$BIN.log" | head -20 >&2 || true
    die "compilation failed; full log: $BIN.log"
  fi
  mv -f "$BIN.tmp.$$" "$BIN"
  log "compiled in $((SECONDS - start)) s: $BIN"
fi

# 3. The models: dynid writes them, with its input pool and torques, so nothing is copied here.
if [[ -z "${DYNID:-}" ]]; then
  DYNID="$ROOT/target/release/dynid"
  if command -v cargo >/dev/null; then
    (cd "$ROOT" && cargo build --release --quiet --bin dynid) || die "cargo build --release --bin dynid failed"
  fi
fi
[[ -x "$DYNID" ]] || die "no dynid binary at $DYNID (cargo build --release --bin dynid, or set DYNID)"
MODELS="$CACHE/models.$$.txt"
trap 'rm -f "$MODELS"' EXIT
"$DYNID" bench-models "$@" --out "$MODELS" || die "$DYNID bench-models $* failed"

# 4. Check, then time.
RUN=()
if [[ -n "${PINBENCH_CPU:-}" ]]; then
  command -v taskset >/dev/null || die "PINBENCH_CPU is set but taskset is missing"
  RUN=(taskset -c "$PINBENCH_CPU")
fi
echo "# cpu: $(grep -m1 'model name' /proc/cpuinfo 2>/dev/null | cut -d: -f2- | sed 's/^ //'), load average $(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo unknown)${PINBENCH_CPU:+, pinned to CPU $PINBENCH_CPU}"
echo "# wheels: ${WHEELS[*]}; compile: $CXX ${FLAGS[*]}"
"${RUN[@]}" "$BIN" "$MODELS"
