//! ROS 2 bags (MCAP files of `sensor_msgs/msg/JointState`) read as a [`Log`], streamed.
//!
//! - **Container**: the `mcap` crate, Foxglove's reference implementation (the format's
//!   maintainers, kept in step with the specification and its conformance tests): its sans-io
//!   [`mcap::sans_io::SummaryReader`] reads the summary at the end of the file (topics, types,
//!   message counts) and [`mcap::sans_io::MessageReader`] then streams the messages chunk by chunk,
//!   decompressing zstd or lz4 and checking every chunk's and the data section's CRC, so a file of
//!   any length is read with the memory of one chunk. It reads from a plain `File` (no memory
//!   map, whose resident pages would grow with the bag).
//! - **Messages**: `cdr.rs`, a small decoder of the one message type (why not a CDR crate: there).
//! - **Joints**: `names.rs` matches each message's `name[]` to the arm's joints.
//! - **Rows**: `reader.rs` merges an arm split over several messages by header stamp and feeds
//!   rows `t, q.., [dq..], [tau..]` into a [`crate::log::TableWriter`], which spills to a
//!   temporary file past [`crate::log::SPILL_ROWS`] rows: memory does not grow with the bag.
//!
//! The time base is the header stamp (`t = 0` at the first row); a topic whose first message
//! has a zero stamp (a driver that does not fill it) uses the MCAP log time instead, and the
//! notes say so. `effort` is the torque (times `--torque-scale` per joint, for drives that
//! publish current); velocity becomes the `dq` columns when every joint has one.
//!
//! Errors name the file, the topic and the message (1-based, counting the topic's messages), say
//! what is wrong and how to fix it; nothing is returned but the error.

mod cdr;
mod names;
mod reader;

use std::fmt;
use std::path::Path;

pub use cdr::{CdrError, JointState};
pub use reader::read;

use crate::log::Log;

/// The ROS 2 message type the reader decodes.
pub const JOINT_STATE: &str = "sensor_msgs/msg/JointState";

/// The first bytes of every MCAP file.
pub const MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// How to read a bag.
#[derive(Debug, Clone, Default)]
pub struct BagOptions {
    /// The topic (default: the only `JointState` topic).
    pub topic: Option<String>,
    /// The arm's joint names in arm order (default: the D-H table's).
    pub joints: Option<Vec<String>>,
    /// Per joint, torque = scale · effort (default 1).
    pub torque_scale: Option<Vec<f64>>,
    /// Whether every row needs an effort for every joint (identification does).
    pub need_effort: bool,
    /// Rows held in memory before spilling (default [`crate::log::SPILL_ROWS`]).
    pub spill_rows: Option<usize>,
}

/// A bag read as a log, and what the reader wants the user to know (time base, topic, what was
/// ignored).
#[derive(Debug)]
pub struct BagLog {
    pub log: Log,
    pub notes: Vec<String>,
    /// The arm's joint names, in arm order, as matched.
    pub joints: Vec<String>,
}

/// Whether `path` is an MCAP file: its extension is `.mcap`, or it starts with the MCAP magic.
pub fn is_bag(path: &Path) -> bool {
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mcap"))
    {
        return true;
    }
    let mut head = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut head))
        .is_ok_and(|()| head == MAGIC)
}

/// A bag that cannot be used: the file, the topic and the message, what and how to fix it.
#[derive(Debug, thiserror::Error)]
pub struct BagError {
    pub file: String,
    pub topic: Option<String>,
    /// 1-based, among the topic's messages.
    pub message: Option<usize>,
    pub kind: Box<BagErrorKind>,
}

impl fmt::Display for BagError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(t) = &self.topic {
            write!(f, ": topic {t}")?;
        }
        if let Some(m) = self.message {
            write!(f, ": message {m}")?;
        }
        write!(f, ": {}", self.kind)
    }
}

/// A topic and its type, for listings.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicInfo {
    pub topic: String,
    pub schema: String,
    pub messages: Option<u64>,
}

fn topic_list(topics: &[TopicInfo]) -> String {
    if topics.is_empty() {
        return "the bag has no topics".into();
    }
    let items: Vec<String> = topics
        .iter()
        .map(|t| match t.messages {
            Some(n) => format!("{} ({}, {n} messages)", t.topic, t.schema),
            None => format!("{} ({})", t.topic, t.schema),
        })
        .collect();
    format!("the bag has {}", items.join(", "))
}

/// What is wrong with a bag.
#[derive(Debug)]
pub enum BagErrorKind {
    Io(std::io::Error),
    Empty,
    NotMcap,
    /// No footer / summary: the recording did not finish.
    Truncated(String),
    /// A CRC mismatch, bad record, bad compression inside the data.
    Corrupt(String),
    NoSummary,
    NoTopic {
        topic: String,
        topics: Vec<TopicInfo>,
    },
    WrongType {
        topic: String,
        schema: String,
        topics: Vec<TopicInfo>,
    },
    NoJointState {
        topics: Vec<TopicInfo>,
    },
    SeveralJointState {
        topics: Vec<TopicInfo>,
    },
    Decode(CdrError),
    JointsFlag(String),
    /// The table has no joint names and `--joints` was not given.
    Unnamed {
        topic_joints: Vec<String>,
    },
    NameTwice {
        name: String,
    },
    MissingJoints {
        missing: Vec<String>,
        origin: &'static str,
        topic_joints: Vec<String>,
    },
    Lengths {
        field: &'static str,
        found: usize,
        names: usize,
    },
    NonFinite {
        field: &'static str,
        joint: String,
        value: f64,
    },
    StampBack {
        stamp: i64,
        previous: i64,
        base: &'static str,
    },
    JointTwiceAtStamp {
        joint: String,
        stamp: i64,
    },
    Incomplete {
        stamp: i64,
        missing: Vec<String>,
    },
    NoVelocity {
        joint: String,
    },
    NoEffort {
        joint: String,
    },
    NoRows,
    TorqueScale(String),
    TempFile(std::io::Error),
}

fn secs(ns: i64) -> String {
    format!(
        "{}.{:09} s",
        ns.div_euclid(1_000_000_000),
        ns.rem_euclid(1_000_000_000)
    )
}

impl fmt::Display for BagErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use BagErrorKind::*;
        match self {
            Io(e) => write!(f, "cannot read the file: {e} — check the path and permissions"),
            Empty => write!(f, "the file is empty — record the bag again (ros2 bag record -s mcap /joint_states)"),
            NotMcap => write!(f, "not an MCAP file (no MCAP magic at the start) — pass a ROS 2 bag recorded with the mcap storage plugin, or a CSV"),
            Truncated(e) => write!(f, "truncated or unfinished bag ({e}) — the recording was cut off: `mcap recover IN.mcap -o OUT.mcap` rewrites what is readable, or `ros2 bag reindex` the bag"),
            Corrupt(e) => write!(f, "corrupt data ({e}) — the file was damaged after recording: copy it again, or `mcap recover` the readable part"),
            NoSummary => write!(f, "the bag has no summary section to list its topics — pass --topic (e.g. --topic /joint_states)"),
            NoTopic { topic, topics } => write!(f, "no topic `{topic}` — {}; pick one with --topic", topic_list(topics)),
            WrongType { topic, schema, topics } => write!(f, "`{topic}` carries {schema}, not {JOINT_STATE} — {}; pick a {JOINT_STATE} topic with --topic", topic_list(topics)),
            NoJointState { topics } => write!(f, "no {JOINT_STATE} topic — {}; record the joint states (ros2 bag record /joint_states)", topic_list(topics)),
            SeveralJointState { topics } => write!(f, "several {JOINT_STATE} topics — {}; pick one with --topic", topic_list(topics)),
            Decode(e) => write!(f, "{e} — the message is damaged or not a ROS 2 JointState"),
            JointsFlag(e) => write!(f, "--joints: {e}"),
            Unnamed { topic_joints } => write!(f, "the D-H table has no joint names to match the bag's joints ({}) — pass --joints with one of those names per joint, in the arm's order, or add `name = \"...\"` to every [[joint]] of the table", topic_joints.join(", ")),
            NameTwice { name } => write!(f, "joint `{name}` appears twice in the message — each joint once per message"),
            MissingJoints { missing, origin, topic_joints } => write!(
                f,
                "the arm's joints {} (from {origin}) are not on the topic, whose joints are {} — fix the names with --joints (one per arm joint, in the arm's order) or in the D-H table",
                missing.join(", "),
                if topic_joints.is_empty() { "none".to_string() } else { topic_joints.join(", ") }
            ),
            Lengths { field, found, names } => write!(f, "{field} has {found} values for {names} names — a JointState needs one per name (or none, for velocity and effort)"),
            NonFinite { field, joint, value } => write!(f, "{field} of `{joint}` is {value} — remove the message or fix the driver"),
            StampBack { stamp, previous, base } => write!(f, "{base} {} is not after the previous row's {} — time must increase: re-record, or sort the bag by time", secs(*stamp), secs(*previous)),
            JointTwiceAtStamp { joint, stamp } => write!(f, "joint `{joint}` is published twice at stamp {} — two publishers on one topic? pick one with --topic or fix the stamps", secs(*stamp)),
            Incomplete { stamp, missing } => write!(f, "the arm's state at stamp {} lacks joints {} (their message was lost) — every stamp needs every joint; cut the bag before the gap", secs(*stamp), missing.join(", ")),
            NoVelocity { joint } => write!(f, "no velocity for `{joint}` although earlier messages had velocities — publish velocity in every message or in none"),
            NoEffort { joint } => write!(f, "no effort for `{joint}` — identification needs the joint torque: publish effort (drives that publish current: add --torque-scale with the torque constants)"),
            NoRows => write!(f, "no message on the topic carries the arm's joints — check --topic and the joint names"),
            TorqueScale(e) => write!(f, "--torque-scale: {e}"),
            TempFile(e) => write!(f, "cannot write the temporary copy of this long bag: {e} — free space in the temporary directory or point TMPDIR elsewhere"),
        }
    }
}

/// `--joints a,b,c` as names.
pub fn parse_joints(s: &str) -> Vec<String> {
    s.split(',').map(|n| n.trim().to_string()).collect()
}

/// `--torque-scale k1,..,kn`: `dof` finite numbers.
pub fn parse_torque_scale(s: &str, dof: usize) -> Result<Vec<f64>, BagErrorKind> {
    let vals: Vec<f64> = s
        .split(',')
        .map(|v| match v.trim().parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(x),
            _ => Err(BagErrorKind::TorqueScale(format!(
                "`{}` is not a finite number — give one factor per joint, e.g. 0.1,0.1",
                v.trim()
            ))),
        })
        .collect::<Result<_, _>>()?;
    if vals.len() != dof {
        return Err(BagErrorKind::TorqueScale(format!(
            "{} factors for an arm with {dof} joints — give one per joint",
            vals.len()
        )));
    }
    Ok(vals)
}
