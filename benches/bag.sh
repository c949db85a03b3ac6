#!/usr/bin/env bash
# Reading ROS 2 bags: a bag of N sensor_msgs/msg/JointState messages of a 7-joint arm (1 kHz,
# position, velocity and effort, zstd chunks of 1 MiB, written by the Python mcap-ros2-support
# writer into target/bag-bench/) read into a Log on one core (taskset), for two lengths: the rate
# (goal ≥ 500,000 messages/s) and the peak RSS (/usr/bin/time -v), which must not grow with N.
#
#   benches/bag.sh                 # 250,000 and 1,000,000 messages
#   benches/bag.sh 100000 400000   # other lengths
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
# shellcheck source=scripts/venv.sh
source scripts/venv.sh
dynid_venv "$ROOT"
LENGTHS=("$@")
[[ ${#LENGTHS[@]} -gt 0 ]] || LENGTHS=(250000 1000000)
DIR=target/bag-bench
mkdir -p "$DIR"
cargo build --release --example bag_read
for n in "${LENGTHS[@]}"; do
  bag="$DIR/arm7_$n.mcap"
  if [[ ! -f "$bag" ]]; then
    echo "writing $bag (Python writer, a few minutes for 10^6 messages) ..." >&2
    python tests/bags/make_bag.py synthetic "$bag.tmp" --messages "$n" --joints 7
    mv "$bag.tmp" "$bag"
  fi
  out="$(/usr/bin/time -v taskset -c 0 target/release/examples/bag_read "$bag" 2>"$DIR/time_$n.txt")"
  rss="$(awk -F': ' '/Maximum resident set size/ {print $2}' "$DIR/time_$n.txt")"
  echo "$out"
  echo "  $n messages, $(du -h "$bag" | cut -f1) bag: max RSS $((rss / 1024)) MB"
done
