//! Joint matching: which entry of a `JointState` message is which joint of the arm, by name.
//!
//! The arm's names come from `--joints a,b,c` or else from the D-H table's joint `name`s (which
//! `import-urdf` writes from the URDF). A message may carry its joints in any order and joints
//! the arm does not have (a gripper on the same topic): those are ignored. A message's names
//! are compared with the previous message's first, so a topic whose messages all list the same
//! joints is matched once.

use std::collections::BTreeSet;

use super::cdr::JointState;
use super::BagErrorKind;

/// The arm's joint names and the last message's mapping.
#[derive(Debug)]
pub struct Matcher {
    /// The arm's joints in arm order.
    pub arm: Vec<String>,
    /// Where the names came from, for messages (`--joints` or the D-H table).
    pub origin: &'static str,
    /// The last message's names (concatenated, NUL-separated) and, per message entry, the arm
    /// joint it is.
    last: Vec<u8>,
    map: Vec<Option<usize>>,
    /// Every name seen on the topic (for the error that lists both sides).
    pub seen: BTreeSet<String>,
}

impl Matcher {
    /// The arm's names: `--joints` (checked against `dof`) or the table's.
    pub fn new(
        dof: usize,
        flag: Option<&[String]>,
        table: Option<Vec<String>>,
    ) -> Result<Matcher, BagErrorKind> {
        let (arm, origin) = match (flag, table) {
            (Some(f), _) => (f.to_vec(), "--joints"),
            (None, Some(t)) => (t, "the D-H table"),
            (None, None) => (Vec::new(), "none"),
        };
        if origin == "--joints" {
            if arm.len() != dof {
                return Err(BagErrorKind::JointsFlag(format!(
                    "{} names for an arm with {dof} joints — give one name per joint, in the arm's order",
                    arm.len()
                )));
            }
            for (k, n) in arm.iter().enumerate() {
                if n.is_empty() {
                    return Err(BagErrorKind::JointsFlag(format!(
                        "name {} is empty — give one name per joint, e.g. --joints shoulder,elbow",
                        k + 1
                    )));
                }
                if arm[..k].contains(n) {
                    return Err(BagErrorKind::JointsFlag(format!(
                        "`{n}` is given twice — each joint needs its own name"
                    )));
                }
            }
        }
        Ok(Matcher {
            arm,
            origin,
            last: Vec::new(),
            map: Vec::new(),
            seen: BTreeSet::new(),
        })
    }

    /// Whether the arm has names to match with.
    pub fn named(&self) -> bool {
        !self.arm.is_empty()
    }

    /// Per entry of the message `js` (decoded from `msg`), the arm joint it is, if any.
    pub fn map(&mut self, js: &JointState, msg: &[u8]) -> Result<&[Option<usize>], BagErrorKind> {
        if !self.same_as_last(js, msg) {
            self.remap(js, msg)?;
        }
        Ok(&self.map)
    }

    fn same_as_last(&self, js: &JointState, msg: &[u8]) -> bool {
        if js.names.len() != self.map.len() {
            return false;
        }
        let mut at = 0;
        for i in 0..js.names.len() {
            let n = js.name(msg, i);
            let end = at + n.len();
            if self.last.get(at..end) != Some(n) || self.last.get(end) != Some(&0) {
                return false;
            }
            at = end + 1;
        }
        at == self.last.len()
    }

    fn remap(&mut self, js: &JointState, msg: &[u8]) -> Result<(), BagErrorKind> {
        self.last.clear();
        self.map.clear();
        let mut used = vec![false; self.arm.len()];
        for i in 0..js.names.len() {
            let raw = js.name(msg, i);
            self.last.extend_from_slice(raw);
            self.last.push(0);
            let name = String::from_utf8_lossy(raw);
            let j = self.arm.iter().position(|a| a.as_bytes() == raw);
            if let Some(j) = j {
                if std::mem::replace(&mut used[j], true) {
                    self.map.clear();
                    self.last.clear();
                    return Err(BagErrorKind::NameTwice {
                        name: name.into_owned(),
                    });
                }
            }
            if !self.seen.contains(name.as_ref()) {
                self.seen.insert(name.into_owned());
            }
            self.map.push(j);
        }
        Ok(())
    }

    /// The error for arm joints that never appeared on the topic: both sides listed.
    pub fn missing(&self, have: u32) -> BagErrorKind {
        let missing: Vec<String> = self
            .arm
            .iter()
            .enumerate()
            .filter(|&(j, _)| have & (1 << j) == 0)
            .map(|(_, n)| n.clone())
            .collect();
        BagErrorKind::MissingJoints {
            missing,
            origin: self.origin,
            topic_joints: self.seen.iter().cloned().collect(),
        }
    }
}
