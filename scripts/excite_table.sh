#!/usr/bin/env bash
# Measures `dynid excite` on the shipped arms at the default budget and prints the table rows of
# docs/excitation.md (arm, family, limits, cond, wall time, feasible). Runs one design at a time;
# each takes both cores. Usage:
#   cargo build --release && scripts/excite_table.sh [EXTRA excite flags]
set -euo pipefail
B=${DYNID:-./target/release/dynid}
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
d2r() { python3 -c "import math,sys; print(','.join(repr(math.radians(float(x))) for x in sys.argv[1:]))" "$@"; }
row() {
    local label=$1 limits=$2; shift 2
    local dir="$OUT/$(echo "$label" | tr -c 'a-zA-Z0-9' _)"
    local start end code=0
    start=$(date +%s.%N)
    "$B" excite "$@" "${EXTRA[@]}" --out "$dir" 2>"$dir.err" || code=$?
    end=$(date +%s.%N)
    local secs
    secs=$(python3 -c "print(f'{$end - $start:.1f}')")
    if [ "$code" = 0 ]; then
        python3 - "$dir/excitation.json" "$label" "$limits" "$secs" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
fam = d["family"]["family"]
print(f"| {sys.argv[2]} | {fam} | {sys.argv[3]} | {len(d['columns'])} | {d['cond']:.1f} | {sys.argv[4]} | "
      f"{'yes' if d['feasible'] else 'no'} ({d['generations']} gen., {d['check_grid_hz']:g} Hz check) |")
PY
    else
        echo "| $label | — | $limits | — | — | $secs | no: exit $code: $(tail -c 160 "$dir.err" | tr '\n' ' ') |"
    fi
}
EXTRA=("$@")
for a in ur5e ur10e panda; do
    row "$a.urdf" "URDF alone" --arm "data/urdf/$a.urdf"
done
row "tiago.urdf (8 DOF)" "URDF alone" --arm data/real/tiago_figaroh/tiago.urdf
for a in ur5e ur10e panda; do
    row "$a.urdf" "URDF + $a.limits.toml" --arm "data/urdf/$a.urdf" --limits "data/urdf/$a.limits.toml"
done
row "tiago.urdf (8 DOF)" "URDF + --ddq-max 0.5,3…" --arm data/real/tiago_figaroh/tiago.urdf --ddq-max 0.5,3,3,3,3,3,3,3
row "ur5e.urdf" "URDF + ur5e.limits.toml" --arm data/urdf/ur5e.urdf --limits data/urdf/ur5e.limits.toml --kind logistic
row "puma560 (generated)" "±2 rad, 2 rad/s, 5 rad/s²" --arm puma560 --q-min -2 --q-max 2 --dq-max 2 --ddq-max 5
# dynamic_calibration's UR10e design limits (experiment_design.m): T = 25 s, N = 7
QMIN=$(d2r -180 -180 -100 -180 -90 -90); QMAX=$(d2r 180 0 100 0 90 90); Q0=$(d2r 0 -90 0 -90 0 0)
row "ur10e.urdf, T 25 s, N 7" "dynamic_calibration's" --arm data/urdf/ur10e.urdf --period 25 --harmonics 7 \
    --q-min="$QMIN" --q-max="$QMAX" --q0="$Q0" --ddq-max 2,1,1,1,1,2.5
