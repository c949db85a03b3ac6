//! Streaming a bag's `JointState` topic into a [`Log`]: the summary first (which topic), then
//! every message once, merged into rows by stamp.
//!
//! Merging: each message adds the arm joints it carries to the row of its stamp. Rows wait in a
//! short queue ordered by stamp (an arm published in parts interleaves its parts, [`WINDOW`]
//! stamps at most) and leave it, in order, once every joint has arrived. A stamp at or before
//! the last row that left is an error (time must increase), and so is a row still incomplete
//! when [`WINDOW`] later stamps are waiting (a lost part); incomplete rows at the very end (the
//! recording stopped between the parts of one state) are dropped and said so.

use std::collections::VecDeque;
use std::fs::File;
use std::io::{Read, Seek};
use std::path::Path;
use std::sync::Arc;

use mcap::sans_io::{
    LinearReaderOptions, MessageReadEvent, MessageReader, SummaryReadEvent, SummaryReader,
};
use mcap::{Channel, McapError, Summary};

use super::cdr::JointState;
use super::names::Matcher;
use super::{BagError, BagErrorKind, BagLog, BagOptions, TopicInfo, JOINT_STATE, MAGIC};
use crate::data::RowLayout;
use crate::log::{Log, TableWriter, SPILL_ROWS};

/// Stamps that may wait for their missing joints.
pub const WINDOW: usize = 64;

/// Longest record read (a corrupt length must not allocate the machine's memory).
const RECORD_LIMIT: usize = 1 << 28;

/// Reads the `JointState` topic of the bag at `path` as a log of a `dof`-joint arm whose joints
/// are called `table_names` (the D-H table's, if it has them; `opts.joints` wins).
pub fn read(
    path: &Path,
    dof: usize,
    table_names: Option<Vec<String>>,
    opts: &BagOptions,
) -> Result<BagLog, BagError> {
    let file = path.display().to_string();
    let fail = |topic: Option<&str>, message: Option<usize>, kind| BagError {
        file: file.clone(),
        topic: topic.map(str::to_string),
        message,
        kind: Box::new(kind),
    };
    check_head(path).map_err(|k| fail(None, None, k))?;
    let summary = read_summary(path).map_err(|k| fail(None, None, k))?;
    let topic =
        select_topic(summary.as_ref(), opts.topic.as_deref()).map_err(|k| fail(None, None, k))?;
    let t = Some(topic.as_str());
    let matcher =
        Matcher::new(dof, opts.joints.as_deref(), table_names).map_err(|k| fail(t, None, k))?;
    let scale = opts.torque_scale.clone().unwrap_or_else(|| vec![1.0; dof]);
    if scale.len() != dof {
        return Err(fail(
            t,
            None,
            BagErrorKind::TorqueScale(format!("{} factors for {dof} joints", scale.len())),
        ));
    }
    let mut merge = Merge::new(dof, scale, opts, matcher);
    let known = summary.as_ref().map(topics);
    stream(path, &topic, known.as_deref(), &mut merge).map_err(|(m, k)| fail(t, m, k))?;
    let messages = merge.messages;
    let joints = merge.matcher.arm.clone();
    let (log, mut notes) = merge.finish(&file).map_err(|k| fail(t, None, k))?;
    notes.insert(
        0,
        format!(
            "{file}: topic {topic}: {messages} messages, {} rows",
            log.len()
        ),
    );
    Ok(BagLog { log, notes, joints })
}

fn check_head(path: &Path) -> Result<(), BagErrorKind> {
    let mut f = File::open(path).map_err(BagErrorKind::Io)?;
    let mut head = Vec::with_capacity(8);
    (&mut f)
        .take(8)
        .read_to_end(&mut head)
        .map_err(BagErrorKind::Io)?;
    match head.len() {
        0 => Err(BagErrorKind::Empty),
        _ if head != MAGIC => Err(BagErrorKind::NotMcap),
        _ => Ok(()),
    }
}

/// The summary section (channels, schemas, counts), `None` when the bag has none.
fn read_summary(path: &Path) -> Result<Option<Summary>, BagErrorKind> {
    let mut f = File::open(path).map_err(BagErrorKind::Io)?;
    let size = f.metadata().map_err(BagErrorKind::Io)?.len();
    let mut r = SummaryReader::new_with_options(
        mcap::sans_io::SummaryReaderOptions::default()
            .with_file_size(size)
            .with_record_length_limit(RECORD_LIMIT),
    );
    while let Some(ev) = r.next_event() {
        match ev.map_err(|e| BagErrorKind::Truncated(e.to_string()))? {
            SummaryReadEvent::ReadRequest(n) => {
                let got = f.read(r.insert(n)).map_err(BagErrorKind::Io)?;
                r.notify_read(got);
            }
            SummaryReadEvent::SeekRequest(to) => {
                let pos = f.seek(to).map_err(BagErrorKind::Io)?;
                r.notify_seeked(pos);
            }
        }
    }
    Ok(r.finish())
}

/// Every topic of the summary with its type and message count, sorted by topic.
fn topics(s: &Summary) -> Vec<TopicInfo> {
    let mut out: Vec<TopicInfo> = Vec::new();
    for c in s.channels.values() {
        let n = s
            .stats
            .as_ref()
            .and_then(|st| st.channel_message_counts.get(&c.id).copied());
        let schema = c
            .schema
            .as_ref()
            .map_or_else(|| "no schema".to_string(), |s| s.name.clone());
        match out.iter_mut().find(|t| t.topic == c.topic) {
            Some(t) => t.messages = t.messages.zip(n).map(|(a, b)| a + b),
            None => out.push(TopicInfo {
                topic: c.topic.clone(),
                schema,
                messages: n,
            }),
        }
    }
    out.sort_by(|a, b| a.topic.cmp(&b.topic));
    out
}

fn is_joint_state(c: &Channel<'_>) -> bool {
    c.message_encoding == "cdr" && c.schema.as_ref().is_some_and(|s| s.name == JOINT_STATE)
}

/// `--topic`, or the only `JointState` topic.
fn select_topic(summary: Option<&Summary>, want: Option<&str>) -> Result<String, BagErrorKind> {
    let Some(s) = summary else {
        return want.map(str::to_string).ok_or(BagErrorKind::NoSummary);
    };
    let all = topics(s);
    if let Some(w) = want {
        let chans: Vec<&Arc<Channel>> = s.channels.values().filter(|c| c.topic == w).collect();
        if chans.is_empty() {
            return Err(BagErrorKind::NoTopic {
                topic: w.into(),
                topics: all,
            });
        }
        if let Some(c) = chans.iter().find(|c| !is_joint_state(c)) {
            let schema = match &c.schema {
                Some(s) if c.message_encoding == "cdr" => s.name.clone(),
                Some(s) => format!("{} ({} encoded)", s.name, c.message_encoding),
                None => format!("schemaless {} data", c.message_encoding),
            };
            return Err(BagErrorKind::WrongType {
                topic: w.into(),
                schema,
                topics: all,
            });
        }
        return Ok(w.into());
    }
    let js: Vec<&TopicInfo> = all.iter().filter(|t| t.schema == JOINT_STATE).collect();
    match js.as_slice() {
        [one] => Ok(one.topic.clone()),
        [] => Err(BagErrorKind::NoJointState { topics: all }),
        _ => Err(BagErrorKind::SeveralJointState { topics: all }),
    }
}

/// An error inside the data: which message (of the topic) it is at or after, and what.
type At = (Option<usize>, BagErrorKind);

fn mcap_error(e: McapError) -> BagErrorKind {
    match e {
        McapError::UnexpectedEof | McapError::BadMagic | McapError::BadFooter => {
            BagErrorKind::Truncated(e.to_string())
        }
        McapError::Io(io) => BagErrorKind::Io(io),
        other => BagErrorKind::Corrupt(other.to_string()),
    }
}

/// Every message of `topic`, decoded, matched and merged.
fn stream(
    path: &Path,
    topic: &str,
    known: Option<&[TopicInfo]>,
    merge: &mut Merge,
) -> Result<(), At> {
    let mut f = File::open(path).map_err(|e| (None, BagErrorKind::Io(e)))?;
    let mut r = MessageReader::new_with_options(
        LinearReaderOptions::default()
            .with_validate_chunk_crcs(true)
            .with_validate_data_section_crc(true)
            .with_record_length_limit(RECORD_LIMIT),
    );
    let mut js = JointState::default();
    // Per channel id: whether it is the topic (`None`: not looked at yet).
    let mut chosen: Vec<Option<bool>> = Vec::new();
    let mut k = 0usize;
    while let Some(ev) = r.next_event() {
        let here = |kind| (if k > 0 { Some(k) } else { None }, kind);
        match ev.map_err(|e| here(mcap_error(e)))? {
            MessageReadEvent::ReadRequest(n) => {
                let got = f.read(r.insert(n)).map_err(|e| here(BagErrorKind::Io(e)))?;
                r.notify_read(got);
            }
            MessageReadEvent::Message(m) => {
                let id = usize::from(m.channel.id);
                if chosen.len() <= id {
                    chosen.resize(id + 1, None);
                }
                let ours = *chosen[id].get_or_insert_with(|| m.channel.topic == topic);
                if !ours {
                    continue;
                }
                k += 1;
                if !is_joint_state(&m.channel) {
                    let schema = m.channel.schema.as_ref().map_or("no schema", |s| &s.name);
                    return Err((
                        Some(k),
                        BagErrorKind::WrongType {
                            topic: topic.into(),
                            schema: schema.into(),
                            topics: known.map(<[_]>::to_vec).unwrap_or_default(),
                        },
                    ));
                }
                js.decode(&m.data)
                    .map_err(|e| (Some(k), BagErrorKind::Decode(e)))?;
                merge
                    .add(&js, &m.data, m.log_time)
                    .map_err(|e| (Some(k), e))?;
            }
        }
    }
    if k == 0 {
        return Err((None, BagErrorKind::NoRows));
    }
    Ok(())
}

/// One row being assembled: the values of the joints that have arrived.
#[derive(Debug, Clone)]
struct Row {
    ns: i64,
    q: Vec<f64>,
    dq: Vec<f64>,
    tau: Vec<f64>,
    have_q: u32,
    have_dq: u32,
    have_tau: u32,
}

/// The merge queue and the table the rows go into.
struct Merge {
    dof: usize,
    full: u32,
    scale: Vec<f64>,
    need_effort: bool,
    spill_rows: usize,
    matcher: Matcher,
    pending: VecDeque<Row>,
    spare: Vec<Row>,
    /// Whether header stamps are the time base (decided by the first message).
    stamps: Option<bool>,
    last_ns: Option<i64>,
    t0: i64,
    /// Arm joints seen on the topic so far.
    seen: u32,
    layout: Option<RowLayout>,
    writer: Option<TableWriter>,
    buf: Vec<f64>,
    /// The current message's entry → arm joint map (reused).
    map: Vec<Option<usize>>,
    rows: usize,
    messages: usize,
    /// Messages that carried none of the arm's joints.
    foreign: usize,
}

impl Merge {
    fn new(dof: usize, scale: Vec<f64>, opts: &BagOptions, matcher: Matcher) -> Merge {
        Merge {
            dof,
            full: (1u32 << dof) - 1,
            scale,
            need_effort: opts.need_effort,
            spill_rows: opts.spill_rows.unwrap_or(SPILL_ROWS),
            matcher,
            pending: VecDeque::new(),
            spare: Vec::new(),
            stamps: None,
            last_ns: None,
            t0: 0,
            seen: 0,
            layout: None,
            writer: None,
            buf: Vec::new(),
            map: Vec::new(),
            rows: 0,
            messages: 0,
            foreign: 0,
        }
    }

    fn base(&self) -> &'static str {
        if self.stamps == Some(false) {
            "log time"
        } else {
            "stamp"
        }
    }

    /// Adds one message's arm joints to the row of its stamp; emits the rows that are complete.
    fn add(&mut self, js: &JointState, msg: &[u8], log_time: u64) -> Result<(), BagErrorKind> {
        self.messages += 1;
        let stamps = *self.stamps.get_or_insert(js.stamp_ns != 0);
        let ns = if stamps {
            js.stamp_ns
        } else {
            i64::try_from(log_time).unwrap_or(i64::MAX)
        };
        let n = js.names.len();
        for (field, len, optional) in [
            ("position", js.position.len(), false),
            ("velocity", js.velocity.len(), true),
            ("effort", js.effort.len(), true),
        ] {
            if len != n && !(optional && len == 0) {
                return Err(BagErrorKind::Lengths {
                    field,
                    found: len,
                    names: n,
                });
            }
        }
        if !self.matcher.named() {
            let topic_joints = (0..n)
                .map(|i| String::from_utf8_lossy(js.name(msg, i)).into_owned())
                .collect();
            return Err(BagErrorKind::Unnamed { topic_joints });
        }
        let mut map = std::mem::take(&mut self.map);
        map.clear();
        map.extend_from_slice(self.matcher.map(js, msg)?);
        if map.iter().all(Option::is_none) {
            self.foreign += 1;
            self.map = map;
            return Ok(());
        }
        let merged = self.merge(js, &map, ns);
        self.map = map;
        merged
    }

    /// Merges one message's joints (`map`: entry → arm joint) into the row of stamp `ns`.
    fn merge(
        &mut self,
        js: &JointState,
        map: &[Option<usize>],
        ns: i64,
    ) -> Result<(), BagErrorKind> {
        if let Some(prev) = self.last_ns.filter(|&p| ns <= p) {
            return Err(BagErrorKind::StampBack {
                stamp: ns,
                previous: prev,
                base: self.base(),
            });
        }
        let slot = self.slot(ns);
        let row = &mut self.pending[slot];
        for (i, j) in map.iter().enumerate() {
            let Some(j) = *j else { continue };
            let name = || self.matcher.arm[j].clone();
            let bit = 1u32 << j;
            if row.have_q & bit != 0 {
                return Err(BagErrorKind::JointTwiceAtStamp {
                    joint: name(),
                    stamp: ns,
                });
            }
            let finite = |field, v: f64| {
                if v.is_finite() {
                    Ok(v)
                } else {
                    Err(BagErrorKind::NonFinite {
                        field,
                        joint: name(),
                        value: v,
                    })
                }
            };
            row.q[j] = finite("position", js.position[i])?;
            row.have_q |= bit;
            if let Some(&v) = js.velocity.get(i) {
                row.dq[j] = finite("velocity", v)?;
                row.have_dq |= bit;
            }
            match js.effort.get(i) {
                Some(&v) => {
                    row.tau[j] = self.scale[j] * finite("effort", v)?;
                    row.have_tau |= bit;
                }
                None if self.need_effort => return Err(BagErrorKind::NoEffort { joint: name() }),
                None => {}
            }
            self.seen |= bit;
        }
        self.drain()?;
        if self.pending.len() > WINDOW {
            return Err(self.incomplete(0));
        }
        Ok(())
    }

    /// The queue index of the row of stamp `ns`, inserted (in stamp order) if new.
    fn slot(&mut self, ns: i64) -> usize {
        let at = self.pending.partition_point(|r| r.ns < ns);
        if self.pending.get(at).is_some_and(|r| r.ns == ns) {
            return at;
        }
        let mut row = self.spare.pop().unwrap_or_else(|| Row {
            ns,
            q: vec![0.0; self.dof],
            dq: vec![0.0; self.dof],
            tau: vec![0.0; self.dof],
            have_q: 0,
            have_dq: 0,
            have_tau: 0,
        });
        (row.ns, row.have_q, row.have_dq, row.have_tau) = (ns, 0, 0, 0);
        self.pending.insert(at, row);
        at
    }

    /// The error for the incomplete row at queue index `i`.
    fn incomplete(&self, i: usize) -> BagErrorKind {
        if self.seen != self.full {
            return self.matcher.missing(self.seen);
        }
        let r = &self.pending[i];
        let missing = (0..self.dof)
            .filter(|&j| r.have_q & (1 << j) == 0)
            .map(|j| self.matcher.arm[j].clone())
            .collect();
        BagErrorKind::Incomplete {
            stamp: r.ns,
            missing,
        }
    }

    /// Emits the complete rows at the front of the queue.
    fn drain(&mut self) -> Result<(), BagErrorKind> {
        while self.pending.front().is_some_and(|r| r.have_q == self.full) {
            let row = self.pending.pop_front().expect("front");
            self.emit(&row)?;
            self.spare.push(row);
        }
        Ok(())
    }

    fn emit(&mut self, row: &Row) -> Result<(), BagErrorKind> {
        let layout = *self.layout.get_or_insert(RowLayout {
            dof: self.dof,
            dq: row.have_dq == self.full,
            ddq: false,
            tau: row.have_tau == self.full,
        });
        let first_missing = |have: u32| {
            let j = (0..self.dof).find(|&j| have & (1 << j) == 0).unwrap_or(0);
            self.matcher.arm[j].clone()
        };
        if layout.dq && row.have_dq != self.full {
            return Err(BagErrorKind::NoVelocity {
                joint: first_missing(row.have_dq),
            });
        }
        if (layout.tau || self.need_effort) && row.have_tau != self.full {
            return Err(BagErrorKind::NoEffort {
                joint: first_missing(row.have_tau),
            });
        }
        if self.rows == 0 {
            self.t0 = row.ns;
        }
        self.buf.clear();
        self.buf.push((row.ns - self.t0) as f64 / 1e9);
        self.buf.extend_from_slice(&row.q);
        if layout.dq {
            self.buf.extend_from_slice(&row.dq);
        }
        if layout.tau {
            self.buf.extend_from_slice(&row.tau);
        }
        let spill = self.spill_rows;
        self.writer
            .get_or_insert_with(|| TableWriter::new(layout.width(), spill))
            .push(&self.buf)
            .map_err(BagErrorKind::TempFile)?;
        self.rows += 1;
        self.last_ns = Some(row.ns);
        Ok(())
    }

    /// The log, and notes on the time base and what was left out.
    fn finish(mut self, file: &str) -> Result<(Log, Vec<String>), BagErrorKind> {
        let mut notes = Vec::new();
        if let Some(i) = self.pending.iter().rposition(|r| r.have_q == self.full) {
            // A complete row behind an incomplete one: a lost part in the middle.
            let gap = self.pending.iter().position(|r| r.have_q != self.full);
            return Err(self.incomplete(gap.unwrap_or(i)));
        }
        if !self.pending.is_empty() {
            if self.seen != self.full {
                return Err(self.matcher.missing(self.seen));
            }
            notes.push(format!(
                "the last {} stamps lack some joints (the recording stopped between the parts of one state): dropped",
                self.pending.len()
            ));
            self.pending.clear();
        }
        let (Some(layout), Some(writer)) = (self.layout, self.writer.take()) else {
            return Err(BagErrorKind::NoRows);
        };
        if self.stamps == Some(false) {
            notes.push(
                "header stamps are zero: the time base is the MCAP log time (when the recorder received each message)".into(),
            );
        } else {
            notes.push(format!(
                "time base: header stamps, t = 0 at {}",
                super::secs(self.t0)
            ));
        }
        if self.foreign > 0 {
            notes.push(format!(
                "{} messages carry none of the arm's joints: ignored",
                self.foreign
            ));
        }
        let others: Vec<&str> = self
            .matcher
            .seen
            .iter()
            .filter(|n| !self.matcher.arm.contains(n))
            .map(String::as_str)
            .collect();
        if !others.is_empty() {
            notes.push(format!(
                "joints not in the arm, ignored: {}",
                others.join(", ")
            ));
        }
        notes.push(format!(
            "joints matched by name ({}): {}",
            self.matcher.origin,
            self.matcher.arm.join(", ")
        ));
        let table = writer.finish().map_err(BagErrorKind::TempFile)?;
        Ok((Log::from_table(file.to_string(), layout, table), notes))
    }
}
