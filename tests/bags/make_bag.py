"""Write ROS 2 bags (MCAP, sensor_msgs/msg/JointState in CDR) with an independent writer.

The writer is the Python `mcap` + `mcap-ros2-support` packages (pinned in tests/requirements.txt),
which share no code with dynid's reader. Used by tests/it/bag.rs and benches/bag.sh.

    make_bag.py --check                                   exit 0 when the writer can be imported
    make_bag.py from-csv CSV OUT --names a,b [options]    one message per CSV row (see --help)
    make_bag.py synthetic OUT --messages N --joints 7     a long bag of a 7-joint arm (benchmark)

Times: the header stamp of row k is EPOCH + t_k exactly (t parsed as a decimal, so a CSV time of
0.002 becomes 2,000,000 ns), the log time 1 ms later.
"""

from __future__ import annotations

import argparse
import csv
import gzip
import math
import sys
from decimal import Decimal

JOINT_STATE = "sensor_msgs/msg/JointState"
MSGDEF = """std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""
STRING_DEF = "string data\n"
EPOCH_NS = 1_700_000_000_123_456_789


def writer(path: str, compression: str, chunk_size: int):
    from mcap.writer import CompressionType
    from mcap_ros2.writer import Writer

    kinds = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
    out = open(path, "wb")  # noqa: SIM115 (closed by the caller)
    return out, Writer(out, chunk_size=chunk_size, compression=kinds[compression])


def joint_state(ns: int, names: list[str], pos: list[float], vel: list[float], eff: list[float]) -> dict:
    return {
        "header": {"stamp": {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}, "frame_id": ""},
        "name": names,
        "position": pos,
        "velocity": vel,
        "effort": eff,
    }


def read_csv(path: str) -> tuple[list[str], list[list[str]]]:
    with open(path, "rb") as f:
        gz = f.read(2) == b"\x1f\x8b"
    opener = gzip.open if gz else open
    with opener(path, "rt") as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    return [h.strip() for h in rows[0]], rows[1:]


def from_csv(a: argparse.Namespace) -> None:
    head, rows = read_csv(a.csv)
    names = a.names.split(",")
    n = len(names)
    col = {h: i for i, h in enumerate(head)}
    has_dq = "dq1" in col and not a.no_velocity
    has_tau = "tau1" in col and not a.no_effort
    gripper = ["gripper_left", "gripper_right"] if a.gripper else []
    out, w = writer(a.out, a.compression, a.chunk_size)
    schema = w.register_msgdef(JOINT_STATE, MSGDEF)
    other = w.register_msgdef("std_msgs/msg/String", STRING_DEF) if a.string_topic else None
    seq = 0
    for k, r in enumerate(rows):
        ns = 0 if a.zero_stamps else EPOCH_NS + int(Decimal(r[col["t"]].strip()) * 1_000_000_000)
        if a.stamp_back is not None and k == a.stamp_back:
            ns -= 3_000_000
        q = [float(r[col[f"q{j + 1}"]]) for j in range(n)]
        dq = [float(r[col[f"dq{j + 1}"]]) for j in range(n)] if has_dq else []
        tau = [float(r[col[f"tau{j + 1}"]]) for j in range(n)] if has_tau else []
        log_time = EPOCH_NS + 1_000_000 + k * 1_000_000
        parts = [list(range(n))]
        if a.split:
            parts = [list(range(n // 2)), list(range(n // 2, n))]
        if a.reverse:
            parts = [p[::-1] for p in parts]
        for p in parts:
            sel = [names[j] for j in p] + (gripper if p is parts[-1] else [])
            pad = [0.25] * len(gripper) if p is parts[-1] else []
            msg = joint_state(
                ns,
                sel,
                [q[j] for j in p] + pad,
                [dq[j] for j in p] + pad if dq else [],
                [tau[j] for j in p] + pad if tau else [],
            )
            w.write_message(a.topic, schema, msg, log_time=log_time, sequence=seq)
            seq += 1
        if a.gripper:
            # The gripper also on its own, at its own rate and stamps.
            g = joint_state(ns + 500_000, gripper, [0.5, 0.5], [], [])
            w.write_message(a.topic, schema, g, log_time=log_time, sequence=seq)
            seq += 1
        if a.second_topic:
            twin = joint_state(ns, names, [2.0 * x for x in q], [], [2.0 * x for x in tau])
            w.write_message(a.second_topic, schema, twin, log_time=log_time, sequence=seq)
            seq += 1
        if other is not None:
            w.write_message(a.string_topic, other, {"data": f"row {k}"}, log_time=log_time, sequence=seq)
            seq += 1
    w.finish()
    out.close()


def synthetic(a: argparse.Namespace) -> None:
    names = [f"joint{j + 1}" for j in range(a.joints)]
    out, w = writer(a.out, a.compression, a.chunk_size)
    schema = w.register_msgdef(JOINT_STATE, MSGDEF)
    dt = 1_000_000  # 1 kHz
    for k in range(a.messages):
        t = k * 1e-3
        q = [math.sin(0.5 * t + j) for j in range(a.joints)]
        dq = [0.5 * math.cos(0.5 * t + j) for j in range(a.joints)]
        tau = [0.1 * j + math.cos(t) for j in range(a.joints)]
        ns = EPOCH_NS + k * dt
        w.write_message("/joint_states", schema, joint_state(ns, names, q, dq, tau), log_time=ns, sequence=k)
    w.finish()
    out.close()


def main() -> int:
    if sys.argv[1:] == ["--check"]:
        import mcap  # noqa: F401
        import mcap_ros2.writer  # noqa: F401

        return 0
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("from-csv")
    c.add_argument("csv")
    c.add_argument("out")
    c.add_argument("--names", required=True, help="the joints' names, in the CSV's order")
    c.add_argument("--topic", default="/joint_states")
    c.add_argument("--gripper", action="store_true", help="two gripper joints in the arm's messages and alone")
    c.add_argument("--reverse", action="store_true", help="joints in reverse order in every message")
    c.add_argument("--split", action="store_true", help="each row as two messages with one stamp")
    c.add_argument("--second-topic", help="a second JointState topic (other values)")
    c.add_argument("--string-topic", help="a std_msgs/msg/String topic beside")
    c.add_argument("--no-velocity", action="store_true")
    c.add_argument("--no-effort", action="store_true")
    c.add_argument("--zero-stamps", action="store_true", help="header stamps 0 (log time is the time base)")
    c.add_argument("--stamp-back", type=int, help="row index whose stamp goes back 3 ms")
    c.add_argument("--compression", default="zstd", choices=["zstd", "lz4", "none"])
    c.add_argument("--chunk-size", type=int, default=1024 * 1024)
    s = sub.add_parser("synthetic")
    s.add_argument("out")
    s.add_argument("--messages", type=int, required=True)
    s.add_argument("--joints", type=int, default=7)
    s.add_argument("--compression", default="zstd", choices=["zstd", "lz4", "none"])
    s.add_argument("--chunk-size", type=int, default=1024 * 1024)
    a = p.parse_args()
    {"from-csv": from_csv, "synthetic": synthetic}[a.cmd](a)
    return 0


if __name__ == "__main__":
    sys.exit(main())
