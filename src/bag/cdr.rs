//! A decoder of the one ROS 2 message the bag reader needs: `sensor_msgs/msg/JointState` in CDR
//! (OMG XCDR version 1, the encoding rosbag2 records; big- and little-endian).
//!
//! ```text
//! JointState: std_msgs/Header header          Header: builtin_interfaces/Time stamp
//!             string[] name                           string frame_id
//!             float64[] position, velocity, effort   Time: int32 sec, uint32 nanosec
//! ```
//!
//! On the wire: a 4-byte encapsulation header (`00 00` big-endian, `00 01` little-endian, two
//! option bytes), then the fields in order, each aligned to its own size (a `float64` to 8)
//! relative to the end of the encapsulation header; a string is a `uint32` length counting its
//! terminating NUL, then the bytes; a sequence a `uint32` count, then the elements. Every read
//! is bounds-checked, and a count is checked against the bytes left before anything is
//! reserved, so a corrupt message is an error, never a panic or a huge allocation.
//!
//! Written here rather than taken from a CDR crate: the general ones (`cdr`, `cdr-encoding`)
//! deserialize through serde into owned `String`s and `Vec`s per message, while this one reuses
//! its buffers and keeps the names as ranges of the message, which is what lets the reader go
//! through a million messages a second; the tests check it against the Python `mcap-ros2-support`
//! serializer and against hand-made big-endian and damaged messages.

use std::fmt;
use std::ops::Range;

/// A decoded `JointState`, its buffers reused from message to message.
#[derive(Debug, Default, Clone)]
pub struct JointState {
    /// Header stamp in nanoseconds (`sec·10⁹ + nanosec`; `sec` may be negative).
    pub stamp_ns: i64,
    /// Each name as a byte range of the message (see [`JointState::name`]).
    pub names: Vec<Range<usize>>,
    pub position: Vec<f64>,
    /// Empty, or one per name.
    pub velocity: Vec<f64>,
    /// Empty, or one per name.
    pub effort: Vec<f64>,
}

/// A message that is not a well-formed CDR `JointState`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CdrError {
    /// Shorter than a field needs.
    Short {
        field: &'static str,
        offset: usize,
        need: usize,
        len: usize,
    },
    /// An encapsulation other than plain CDR.
    Encapsulation { kind: [u8; 2] },
    /// A string without its terminating NUL.
    Unterminated { field: &'static str, offset: usize },
}

impl fmt::Display for CdrError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CdrError::Short {
                field,
                offset,
                need,
                len,
            } => write!(
                f,
                "not a sensor_msgs/msg/JointState: `{field}` needs {need} bytes at offset {offset} of a {len}-byte message"
            ),
            CdrError::Encapsulation { kind } => write!(
                f,
                "CDR encapsulation {:02x}{:02x} is not plain CDR (0000 big-endian, 0001 little-endian); XCDR2 and parameter lists are not read",
                kind[0], kind[1]
            ),
            CdrError::Unterminated { field, offset } => {
                write!(f, "`{field}` at offset {offset} is a string without its terminating NUL")
            }
        }
    }
}

/// A cursor over the message body; offsets (and alignment) count from the end of the
/// encapsulation header.
struct Cursor<'a> {
    body: &'a [u8],
    at: usize,
    little: bool,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, field: &'static str) -> Result<&'a [u8], CdrError> {
        match self.body.get(self.at..self.at.saturating_add(n)) {
            Some(b) => {
                self.at += n;
                Ok(b)
            }
            None => Err(CdrError::Short {
                field,
                offset: self.at + 4,
                need: n,
                len: self.body.len() + 4,
            }),
        }
    }

    fn align(&mut self, to: usize, field: &'static str) -> Result<(), CdrError> {
        let pad = (to - self.at % to) % to;
        self.take(pad, field).map(|_| ())
    }

    fn u32(&mut self, field: &'static str) -> Result<u32, CdrError> {
        self.align(4, field)?;
        let b: [u8; 4] = self.take(4, field)?.try_into().expect("4 bytes");
        Ok(if self.little {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    }

    /// A string as a range of the whole message (the NUL left out).
    fn string(&mut self, field: &'static str) -> Result<Range<usize>, CdrError> {
        let n = self.u32(field)? as usize;
        let start = self.at;
        let s = self.take(n, field)?;
        match s.last() {
            // A zero length (some writers' empty string) has no NUL to strip.
            None => Ok(start + 4..start + 4),
            Some(0) => Ok(start + 4..start + 4 + n - 1),
            Some(_) => Err(CdrError::Unterminated {
                field,
                offset: start + 4,
            }),
        }
    }

    fn f64s(&mut self, out: &mut Vec<f64>, field: &'static str) -> Result<(), CdrError> {
        let n = self.u32(field)? as usize;
        out.clear();
        if n == 0 {
            return Ok(());
        }
        self.align(8, field)?;
        let bytes = self.take(n.saturating_mul(8), field)?;
        out.extend(bytes.chunks_exact(8).map(|c| {
            let b: [u8; 8] = c.try_into().expect("8 bytes");
            if self.little {
                f64::from_le_bytes(b)
            } else {
                f64::from_be_bytes(b)
            }
        }));
        Ok(())
    }
}

impl JointState {
    /// Decodes `msg` (a whole CDR message, encapsulation header included) into `self`.
    pub fn decode(&mut self, msg: &[u8]) -> Result<(), CdrError> {
        let short = |field| CdrError::Short {
            field,
            offset: 0,
            need: 4,
            len: msg.len(),
        };
        let head = msg.get(..4).ok_or_else(|| short("encapsulation header"))?;
        let little = match [head[0], head[1]] {
            [0, 0] => false,
            [0, 1] => true,
            kind => return Err(CdrError::Encapsulation { kind }),
        };
        let mut c = Cursor {
            body: &msg[4..],
            at: 0,
            little,
        };
        let sec = c.u32("header.stamp.sec")? as i32;
        let nanosec = c.u32("header.stamp.nanosec")?;
        self.stamp_ns = i64::from(sec) * 1_000_000_000 + i64::from(nanosec);
        c.string("header.frame_id")?;
        let count = c.u32("name")? as usize;
        // Each name takes at least 4 bytes: a corrupt count cannot reserve more than the message.
        if count > c.body.len().saturating_sub(c.at) / 4 {
            return Err(CdrError::Short {
                field: "name",
                offset: c.at + 4,
                need: count.saturating_mul(4),
                len: msg.len(),
            });
        }
        self.names.clear();
        for _ in 0..count {
            let r = c.string("name[]")?;
            self.names.push(r);
        }
        c.f64s(&mut self.position, "position")?;
        c.f64s(&mut self.velocity, "velocity")?;
        c.f64s(&mut self.effort, "effort")?;
        Ok(())
    }

    /// Name `i` as bytes of `msg` (the message [`JointState::decode`] read).
    pub fn name<'m>(&self, msg: &'m [u8], i: usize) -> &'m [u8] {
        &msg[self.names[i].clone()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A JointState written field by field as the CDR rules say (the oracle for big-endian,
    /// which no Python writer emits).
    fn encode(little: bool, sec: i32, nsec: u32, names: &[&str], arrays: [&[f64]; 3]) -> Vec<u8> {
        let mut b = vec![0, u8::from(little), 0, 0];
        let align = |b: &mut Vec<u8>, n: usize| {
            while !(b.len() - 4).is_multiple_of(n) {
                b.push(0);
            }
        };
        let u32b = |v: u32| {
            if little {
                v.to_le_bytes()
            } else {
                v.to_be_bytes()
            }
        };
        let string = |b: &mut Vec<u8>, s: &str| {
            align(b, 4);
            b.extend(u32b(s.len() as u32 + 1));
            b.extend(s.as_bytes());
            b.push(0);
        };
        b.extend(u32b(sec as u32));
        b.extend(u32b(nsec));
        string(&mut b, "base_link");
        align(&mut b, 4);
        b.extend(u32b(names.len() as u32));
        for n in names {
            string(&mut b, n);
        }
        for a in arrays {
            align(&mut b, 4);
            b.extend(u32b(a.len() as u32));
            if !a.is_empty() {
                align(&mut b, 8);
            }
            for v in a {
                b.extend(if little {
                    v.to_le_bytes()
                } else {
                    v.to_be_bytes()
                });
            }
        }
        b
    }

    #[test]
    fn both_byte_orders_decode_to_the_encoded_fields() {
        for little in [true, false] {
            let msg = encode(
                little,
                -3,
                999_999_999,
                &["a", "joint_two", "c3"],
                [&[1.5, -2.25, 1e-300], &[], &[0.1, 0.2, -0.3]],
            );
            let mut js = JointState::default();
            js.decode(&msg).unwrap();
            assert_eq!(js.stamp_ns, -3_000_000_000 + 999_999_999);
            let names: Vec<&[u8]> = (0..3).map(|i| js.name(&msg, i)).collect();
            assert_eq!(names, [&b"a"[..], b"joint_two", b"c3"]);
            assert_eq!(js.position, [1.5, -2.25, 1e-300]);
            assert!(js.velocity.is_empty());
            assert_eq!(js.effort, [0.1, 0.2, -0.3]);
        }
    }

    #[test]
    fn every_truncation_and_a_huge_count_are_errors_not_panics() {
        let msg = encode(
            true,
            1,
            2,
            &["a", "b"],
            [&[1.0, 2.0], &[3.0, 4.0], &[5.0, 6.0]],
        );
        let mut js = JointState::default();
        js.decode(&msg).unwrap();
        for n in 0..msg.len() {
            // The last array's final bytes are all needed; any shorter message fails.
            assert!(js.decode(&msg[..n]).is_err(), "{n} bytes decoded");
        }
        let mut huge = msg.clone();
        // name count (offset 4 + 8 stamp + 4 + 10 "base_link\0" + 2 pad = 28)
        huge[28..32].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(
            js.decode(&huge),
            Err(CdrError::Short { field: "name", .. })
        ));
        let mut xcdr2 = msg.clone();
        xcdr2[1] = 7;
        assert_eq!(
            js.decode(&xcdr2),
            Err(CdrError::Encapsulation { kind: [0, 7] })
        );
        let mut unterminated = msg;
        unterminated[4 + 8 + 4 + 9] = b'x';
        assert!(matches!(
            js.decode(&unterminated),
            Err(CdrError::Unterminated { .. })
        ));
    }
}
