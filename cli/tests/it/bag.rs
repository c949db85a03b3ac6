//! ROS 2 bags in. The oracle: bags written by an independent writer (the Python `mcap` +
//! `mcap-ros2-support` packages that scripts/test.sh installs into `.venv/`, driven by
//! `tests/bags/make_bag.py`) from CSVs, which must read back as those CSVs exactly (the values
//! are float64 in both, the stamps exact nanoseconds of the CSV's decimal times), and identify to
//! the same result. Without the writer the tests fail and say how to install it.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use dynid::data::{write_header, write_row, Trajectory};
use dynid::dh::DhTable;

use crate::common::{dynid, project_python};

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Runs `tests/bags/make_bag.py ARGS`; panics (never skips) when the writer is missing.
fn make_bag(args: &[&str]) {
    let script =
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("tests/bags/make_bag.py");
    let python = project_python();
    let check = Command::new(&python).arg(&script).arg("--check").output();
    match check {
        Ok(o) if o.status.success() => {}
        other => panic!(
            "the bag writer (Python mcap + mcap-ros2-support) cannot run with {}: {} — run \
             scripts/test.sh (it sets up .venv/ with the pinned packages), or set DYNID_PYTHON \
             to an interpreter that has `pip install -r requirements.txt`",
            python.display(),
            match other {
                Ok(o) => text(&o),
                Err(e) => e.to_string(),
            }
        ),
    }
    let o = Command::new(&python)
        .arg(&script)
        .args(args)
        .output()
        .expect("run make_bag.py");
    assert!(o.status.success(), "make_bag.py {args:?}: {}", text(&o));
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// A 2-joint log at 1 kHz with every block a bag can carry (t, q, dq, tau).
fn small_csv(dir: &Path, rows: usize) -> PathBuf {
    let path = dir.join("small.csv");
    let mut f = std::fs::File::create(&path).unwrap();
    let h: Vec<String> = ["t", "q1", "q2", "dq1", "dq2", "tau1", "tau2"]
        .map(String::from)
        .to_vec();
    write_header(&mut f, &h).unwrap();
    for k in 0..rows {
        let t = k as f64 / 1000.0;
        let row = [
            t,
            (3.0 * t).sin(),
            -0.3 + t,
            3.0 * (3.0 * t).cos(),
            1.0,
            2.0 + (5.0 * t).sin() / 3.0,
            -1.0 / 7.0 * t,
        ];
        write_row(&mut f, &row).unwrap();
    }
    path
}

fn read(path: &Path) -> Trajectory {
    Trajectory::from_path(path, Some(2)).unwrap_or_else(|e| panic!("{e}"))
}

/// Converts `bag` with `extra` options; the CSV it wrote.
fn convert(bag: &Path, out: &Path, extra: &[&str]) -> Trajectory {
    let mut args = vec!["convert", s(bag), "--arm", "planar2", "--out", s(out)];
    args.extend_from_slice(extra);
    let o = dynid(&args);
    assert!(o.status.success(), "{}", text(&o));
    read(out)
}

#[test]
fn gripper_joints_other_orders_split_messages_and_second_topics_read_as_the_csv() {
    let dir = tempfile::tempdir().unwrap();
    let csv = small_csv(dir.path(), 300);
    let want = read(&csv);
    let cases: [(&str, &[&str], &[&str]); 4] = [
        ("plain", &[], &[]),
        ("gripper_reversed", &["--gripper", "--reverse"], &[]),
        (
            "split",
            &["--split", "--gripper", "--compression", "lz4"],
            &[],
        ),
        (
            "two_topics",
            &[
                "--second-topic",
                "/twin/joint_states",
                "--string-topic",
                "/chatter",
                "--compression",
                "none",
            ],
            &["--topic", "/joint_states"],
        ),
    ];
    for (name, make, read_opts) in cases {
        let bag = dir.path().join(format!("{name}.mcap"));
        let mut args = vec!["from-csv", s(&csv), s(&bag), "--names", "shoulder,elbow"];
        args.extend_from_slice(make);
        make_bag(&args);
        let out = dir.path().join(format!("{name}.csv"));
        let mut opts = vec!["--joints", "shoulder,elbow"];
        opts.extend_from_slice(read_opts);
        let mut got = convert(&bag, &out, &opts);
        got.source = want.source.clone();
        assert_eq!(got, want, "{name}");
    }
    // The joints given the other way round are the columns the other way round.
    let bag = dir.path().join("plain.mcap");
    let swapped = convert(
        &bag,
        &dir.path().join("sw.csv"),
        &["--joints", "elbow,shoulder"],
    );
    assert_eq!(swapped.q[0], want.q[1]);
    assert_eq!(
        swapped.tau.as_ref().unwrap()[1],
        want.tau.as_ref().unwrap()[0]
    );
    // The second topic is picked by --topic, and it is the other data (2x, no velocity).
    let bag = dir.path().join("two_topics.mcap");
    let twin = convert(
        &bag,
        &dir.path().join("twin.csv"),
        &[
            "--joints",
            "shoulder,elbow",
            "--topic",
            "/twin/joint_states",
        ],
    );
    assert!(twin.dq.is_none());
    assert_eq!(twin.q[5], 2.0 * want.q[5]);
    // The gripper's joints are named as ignored.
    let o = dynid(&[
        "convert",
        s(&dir.path().join("gripper_reversed.mcap")),
        "--joints",
        "shoulder,elbow",
    ]);
    assert!(
        text(&o).contains("ignored: gripper_left, gripper_right"),
        "{}",
        text(&o)
    );
    assert!(text(&o).contains("300 messages carry none of the arm's joints"));
}

#[test]
fn zero_stamps_fall_back_to_log_time_and_say_so() {
    let dir = tempfile::tempdir().unwrap();
    let csv = small_csv(dir.path(), 50);
    let bag = dir.path().join("zero.mcap");
    make_bag(&[
        "from-csv",
        s(&csv),
        s(&bag),
        "--names",
        "a,b",
        "--zero-stamps",
    ]);
    let out = dir.path().join("zero.csv");
    let o = dynid(&["convert", s(&bag), "--joints", "a,b", "--out", s(&out)]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("time base is the MCAP log time"),
        "{}",
        text(&o)
    );
    // make_bag.py logs row k at EPOCH + 1 ms + k ms: the CSV's own times.
    assert_eq!(read(&out).t, read(&csv).t);
}

/// The tables and the shared planar2 set as the CSV tests use it: a bag of it identifies to the
/// same effects and the same errors (to 1e-12 relative: the inputs are bit-identical, so any
/// difference would be the reader's).
#[test]
fn a_bag_of_the_shared_set_identifies_like_the_csv() {
    let dir = tempfile::tempdir().unwrap();
    let d = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .join("data/sim/planar2_paper_friction");
    // The arm with joint names, as import-urdf writes them: no --joints needed.
    let arm = std::fs::read_to_string(d.join("arm.toml")).unwrap();
    let mut named = String::new();
    let mut k = 0;
    for line in arm.lines() {
        named += line;
        named.push('\n');
        if line == "[[joint]]" {
            k += 1;
            named += &format!("name = \"{}\"\n", ["shoulder", "elbow"][k - 1]);
        }
    }
    let arm_path = dir.path().join("planar2_paper.toml");
    std::fs::write(&arm_path, named).unwrap();
    let mut bags = Vec::new();
    for f in ["excite_noisy", "validate_noisy"] {
        let bag = dir.path().join(format!("{f}.mcap"));
        let csv = d.join(format!("{f}.csv.gz"));
        make_bag(&[
            "from-csv",
            s(&csv),
            s(&bag),
            "--names",
            "shoulder,elbow",
            "--gripper",
        ]);
        bags.push(bag);
    }
    let run = |data: &Path, val: &Path, out: &str| -> serde_json::Value {
        let out = dir.path().join(out);
        let o = dynid(&[
            "identify",
            "--arm",
            s(&arm_path),
            "--data",
            s(data),
            "--validate",
            s(val),
            "--physical",
            "off",
            "--out",
            s(&out),
        ]);
        assert!(o.status.success(), "{}", text(&o));
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
    };
    let from_bag = run(&bags[0], &bags[1], "bag");
    let from_csv = run(
        &d.join("excite_noisy.csv.gz"),
        &d.join("validate_noisy.csv.gz"),
        "csv",
    );
    let labels = |j: &serde_json::Value| -> Vec<String> {
        j["effects_found"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| format!("{}{}", e["effect"], e["joint"]))
            .collect()
    };
    assert_eq!(labels(&from_bag), labels(&from_csv));
    assert!(labels(&from_csv).len() >= 4, "{:?}", labels(&from_csv));
    let mut compared = 0;
    same_numbers(
        &from_bag["error"],
        &from_csv["error"],
        "error",
        &mut compared,
    );
    same_numbers(
        &from_bag["theta"],
        &from_csv["theta"],
        "theta",
        &mut compared,
    );
    assert!(compared > 20, "{compared} numbers compared");
}

/// Every number in `a` equals the one in `b` to 1e-12 relative; the structure is the same.
fn same_numbers(a: &serde_json::Value, b: &serde_json::Value, at: &str, n: &mut usize) {
    use serde_json::Value as V;
    match (a, b) {
        (V::Number(x), V::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            assert!(
                (x - y).abs() <= 1e-12 * x.abs().max(y.abs()),
                "{at}: {x} vs {y}"
            );
            *n += 1;
        }
        (V::Array(x), V::Array(y)) => {
            assert_eq!(x.len(), y.len(), "{at}");
            for (i, (x, y)) in x.iter().zip(y).enumerate() {
                same_numbers(x, y, &format!("{at}[{i}]"), n);
            }
        }
        (V::Object(x), V::Object(y)) => {
            assert_eq!(
                x.keys().collect::<Vec<_>>(),
                y.keys().collect::<Vec<_>>(),
                "{at}"
            );
            for (k, v) in x {
                same_numbers(v, &y[k], &format!("{at}.{k}"), n);
            }
        }
        _ => assert_eq!(a, b, "{at}"),
    }
}

/// Runs `convert` expecting exit 2, no output file, and every `needles` in the message.
fn rejected(args: &[&str], out: &Path, needles: &[&str]) {
    let mut a = args.to_vec();
    a.extend_from_slice(&["--out", s(out)]);
    let o = dynid(&a);
    let msg = text(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {msg}");
    assert!(!out.exists(), "{args:?} wrote {}", out.display());
    for n in needles {
        assert!(msg.contains(n), "{args:?}: `{n}` not in: {msg}");
    }
    assert!(msg.contains(" — "), "no fix in: {msg}");
}

#[test]
fn bad_topics_and_joint_names_are_errors_that_list_both_sides() {
    let dir = tempfile::tempdir().unwrap();
    let csv = small_csv(dir.path(), 40);
    let bag = dir.path().join("b.mcap");
    make_bag(&[
        "from-csv",
        s(&csv),
        s(&bag),
        "--names",
        "shoulder,elbow",
        "--gripper",
        "--second-topic",
        "/twin",
        "--string-topic",
        "/chatter",
    ]);
    let b = s(&bag);
    let out = dir.path().join("out.csv");
    let j = ["--joints", "shoulder,elbow"];
    // Two JointState topics and no --topic: both listed, with their types and counts.
    rejected(
        &["convert", b, j[0], j[1]],
        &out,
        &[
            b,
            "several",
            "/joint_states (sensor_msgs/msg/JointState, 80 messages)",
            "/twin (",
            "--topic",
        ],
    );
    rejected(
        &["convert", b, j[0], j[1], "--topic", "/nope"],
        &out,
        &["no topic `/nope`", "/chatter (std_msgs/msg/String"],
    );
    rejected(
        &["convert", b, j[0], j[1], "--topic", "/chatter"],
        &out,
        &["carries std_msgs/msg/String"],
    );
    // Names the topic does not have: both sides listed.
    let args = [
        "convert",
        b,
        "--topic",
        "/joint_states",
        "--joints",
        "shoulder,wrist",
    ];
    rejected(
        &args,
        &out,
        &[
            "topic /joint_states",
            "wrist",
            "gripper_left, gripper_right, shoulder",
        ],
    );
    // A table without names and no --joints: the error says --joints.
    rejected(
        &["convert", b, "--arm", "planar2", "--topic", "/twin"],
        &out,
        &["no joint names", "--joints", "shoulder, elbow"],
    );
    rejected(
        &["convert", b, "--topic", "/twin", "--joints", "a,a"],
        &out,
        &["given twice"],
    );
    rejected(
        &[
            "convert", b, "--arm", "planar2", "--topic", "/twin", "--joints", "a",
        ],
        &out,
        &["1 names for an arm with 2 joints"],
    );
    // identify needs effort; the twin topic has it but no velocity, make one without effort.
    let noeff = dir.path().join("noeff.mcap");
    make_bag(&[
        "from-csv",
        s(&csv),
        s(&noeff),
        "--names",
        "a,b",
        "--no-effort",
    ]);
    let o = dynid(&[
        "identify",
        "--arm",
        "planar2",
        "--data",
        s(&noeff),
        "--joints",
        "a,b",
        "--out",
        s(&out),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains("message 1: no effort for `a`"),
        "{}",
        text(&o)
    );
    assert!(text(&o).contains("--torque-scale"));
    assert!(!out.exists());
}

#[test]
fn stamps_that_go_back_and_empty_truncated_or_corrupt_bags_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let csv = small_csv(dir.path(), 200);
    let out = dir.path().join("out.csv");
    let j = ["--joints", "a,b"];
    let back = dir.path().join("back.mcap");
    make_bag(&[
        "from-csv",
        s(&csv),
        s(&back),
        "--names",
        "a,b",
        "--stamp-back",
        "7",
    ]);
    rejected(
        &["convert", s(&back), j[0], j[1]],
        &out,
        &["topic /joint_states: message 8: stamp", "is not after"],
    );
    let empty = dir.path().join("empty.mcap");
    std::fs::write(&empty, b"").unwrap();
    rejected(
        &["convert", s(&empty), j[0], j[1]],
        &out,
        &[s(&empty), "the file is empty"],
    );
    let csv_as_bag = dir.path().join("notabag.mcap");
    std::fs::copy(&csv, &csv_as_bag).unwrap();
    rejected(
        &["convert", s(&csv_as_bag), j[0], j[1]],
        &out,
        &["not an MCAP file"],
    );
    // Uncompressed, so the flipped byte is a value's: only the chunk CRC can catch it.
    let good = dir.path().join("good.mcap");
    make_bag(&[
        "from-csv",
        s(&csv),
        s(&good),
        "--names",
        "a,b",
        "--compression",
        "none",
    ]);
    let bytes = std::fs::read(&good).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    rejected(
        &["convert", s(&cut), j[0], j[1]],
        &out,
        &[s(&cut), "truncated or unfinished", "mcap recover"],
    );
    let want = read(&csv);
    let needle = want.q[2 * 100 + 1].to_le_bytes();
    let at = bytes
        .windows(8)
        .position(|w| w == needle)
        .expect("value in the file");
    let mut bad = bytes.clone();
    bad[at] ^= 0x01;
    let corrupt = dir.path().join("corrupt.mcap");
    std::fs::write(&corrupt, &bad).unwrap();
    rejected(
        &["convert", s(&corrupt), j[0], j[1]],
        &out,
        &[
            s(&corrupt),
            "topic /joint_states",
            "Chunk CRC failed",
            "corrupt data",
        ],
    );
}

#[test]
fn joint_names_in_tables_are_validated_and_written_by_import_urdf() {
    let table = |names: [&str; 2]| {
        let mut t =
            String::from("name = \"n\"\nconvention = \"modified\"\ngravity = [0.0, 0.0, -9.81]\n");
        for n in names {
            t += &format!("[[joint]]\nname = \"{n}\"\nkind = \"revolute\"\nalpha = 0.0\na = 0.5\nd = 0.0\ntheta = 0.0\n");
        }
        DhTable::from_str(&t, "n.toml")
    };
    assert_eq!(
        table(["a", "b"]).unwrap().joint_names().unwrap(),
        ["a", "b"]
    );
    for (names, needle) in [
        (
            ["a", "a"],
            "joint[2].name: joint name `a` is already used by joint 1",
        ),
        (["a", ""], "is empty"),
        (["a,b", "c"], "has a comma"),
        ([" a", "c"], "surrounding spaces"),
    ] {
        let e = table(names).unwrap_err().to_string();
        assert!(e.contains(needle), "{names:?}: {e}");
    }
    let dir = tempfile::tempdir().unwrap();
    let urdf = dir.path().join("two.urdf");
    let link = |n: &str| {
        format!("<link name=\"{n}\"><inertial><mass value=\"1\"/><inertia ixx=\"0.1\" ixy=\"0\" ixz=\"0\" iyy=\"0.1\" iyz=\"0\" izz=\"0.1\"/></inertial></link>")
    };
    let joint = |n: &str, p: &str, c: &str| {
        format!("<joint name=\"{n}\" type=\"revolute\"><parent link=\"{p}\"/><child link=\"{c}\"/><origin xyz=\"0.3 0 0\"/><axis xyz=\"0 0 1\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/></joint>")
    };
    std::fs::write(
        &urdf,
        format!(
            "<robot name=\"two\">{}{}{}{}{}</robot>",
            link("base"),
            link("l1"),
            link("l2"),
            joint("hip_pitch", "base", "l1"),
            joint("knee_pitch", "l1", "l2")
        ),
    )
    .unwrap();
    let o = dynid(&["import-urdf", s(&urdf), "--out", s(dir.path())]);
    assert!(o.status.success(), "{}", text(&o));
    let t = DhTable::from_path(&dir.path().join("two.toml")).unwrap();
    assert_eq!(t.joint_names().unwrap(), ["hip_pitch", "knee_pitch"]);
    // ... and that arm reads its bag with no flag.
    let csv = small_csv(dir.path(), 30);
    let bag = dir.path().join("two.mcap");
    make_bag(&[
        "from-csv",
        s(&csv),
        s(&bag),
        "--names",
        "hip_pitch,knee_pitch",
        "--reverse",
    ]);
    let out = dir.path().join("two.csv");
    let o = dynid(&[
        "convert",
        s(&bag),
        "--arm",
        s(&dir.path().join("two.toml")),
        "--out",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let mut got = read(&out);
    got.source = read(&csv).source;
    assert_eq!(got, read(&csv));
}

/// `torque` reads a bag through the same opener as `identify`: the same output as from the
/// CSV the bag was made of (inverse dynamics of identical rows: equal bytes).
#[test]
fn torque_from_a_bag_equals_torque_from_its_csv() {
    let dir = tempfile::tempdir().unwrap();
    let csv = small_csv(dir.path(), 400);
    let bag = dir.path().join("t.mcap");
    make_bag(&["from-csv", s(&csv), s(&bag), "--names", "a,b", "--gripper"]);
    let params = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .join("docs/examples/planar2_spring.params.toml");
    let run = |data: &Path, extra: &[&str], out: &str| {
        let out = dir.path().join(out);
        let mut args = vec![
            "torque",
            "--arm",
            "planar2",
            "--params",
            s(&params),
            "--data",
            s(data),
        ];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["--cutoff", "20", "--out", s(&out)]);
        let o = dynid(&args);
        assert!(o.status.success(), "{}", text(&o));
        std::fs::read_to_string(out).unwrap()
    };
    let from_bag = run(&bag, &["--joints", "a,b"], "bag.csv");
    assert_eq!(from_bag, run(&csv, &[], "csv.csv"));
    assert_eq!(from_bag.lines().count(), 401);
}
