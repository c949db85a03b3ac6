//! A data file's samples as identification reads them: window by window, never all at once.
//!
//! [`Log::open`] streams the CSV (or `.csv.gz`) once, checking every cell (see [`crate::data`]).
//! A log of up to [`SPILL_ROWS`] rows is kept in memory; a longer one is written, row by row as
//! it is parsed, to an unnamed temporary file (removed by the OS when the log is dropped, even
//! on a crash) in the canonical row order `t, q.., [dq..], [ddq..], [tau..]` as raw `f64`s, and
//! windows are read back from it by position. Either way every consumer sees the same thing:
//! [`Log::read`] copies rows `r0..r1` out as a [`Trajectory`], so memory use is that of the
//! windows in flight, whatever the length of the log. The store is a [`Table`] of `f64` rows,
//! which identification also uses for its long outputs (validation predictions).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::sync::Arc;

use crate::data::{self, DataError, DataErrorKind, RowLayout, Trajectory};
use crate::diag::Location;

/// Rows kept in memory before a log is spilled to a temporary file (13.6 MB for a 6-joint log
/// with torques).
pub const SPILL_ROWS: usize = 1 << 17;

/// Rows of `width` values, appended in order ([`TableWriter`]) and then read back in any order:
/// in memory up to a number of rows, beyond it in an unnamed temporary file.
#[derive(Debug)]
pub struct Table {
    width: usize,
    rows: usize,
    store: Store,
}

#[derive(Debug)]
enum Store {
    /// Row-major rows.
    Memory(Vec<f64>),
    /// The same rows as little-endian `f64`s in an unnamed temporary file.
    Disk(File),
}

/// Builds a [`Table`] row by row, spilling to a temporary file beyond `spill_rows` rows.
#[derive(Debug)]
pub struct TableWriter {
    width: usize,
    rows: usize,
    spill_rows: usize,
    mem: Vec<f64>,
    disk: Option<BufWriter<File>>,
}

impl TableWriter {
    pub fn new(width: usize, spill_rows: usize) -> Self {
        TableWriter {
            width,
            rows: 0,
            spill_rows: spill_rows.max(1),
            mem: Vec::new(),
            disk: None,
        }
    }

    /// Appends one row (`width` values).
    pub fn push(&mut self, row: &[f64]) -> std::io::Result<()> {
        debug_assert_eq!(row.len(), self.width);
        self.rows += 1;
        if let Some(w) = self.disk.as_mut() {
            return write_f64s(w, row);
        }
        self.mem.extend_from_slice(row);
        if self.rows >= self.spill_rows {
            let mut w = BufWriter::with_capacity(1 << 16, tempfile::tempfile()?);
            write_f64s(&mut w, &self.mem)?;
            self.mem = Vec::new();
            self.disk = Some(w);
        }
        Ok(())
    }

    pub fn finish(self) -> std::io::Result<Table> {
        let store = match self.disk {
            Some(w) => Store::Disk(w.into_inner().map_err(|e| e.into_error())?),
            None => Store::Memory(self.mem),
        };
        Ok(Table {
            width: self.width,
            rows: self.rows,
            store,
        })
    }
}

impl Table {
    pub fn len(&self) -> usize {
        self.rows
    }

    pub fn is_empty(&self) -> bool {
        self.rows == 0
    }

    pub fn width(&self) -> usize {
        self.width
    }

    /// Whether the rows live in a temporary file.
    pub fn spilled(&self) -> bool {
        matches!(self.store, Store::Disk(_))
    }

    /// Calls `f` with each of rows `a..b` in turn: straight from memory, or read back from the
    /// temporary file in pieces.
    pub fn rows(&self, a: usize, b: usize, mut f: impl FnMut(&[f64])) {
        let w = self.width;
        let b = b.min(self.rows);
        let a = a.min(b);
        match &self.store {
            Store::Memory(v) => v[a * w..b * w].chunks_exact(w).for_each(f),
            Store::Disk(file) => {
                const ROWS: usize = 4096;
                let mut bytes = vec![0u8; ROWS.min(b - a) * w * 8];
                let mut vals = vec![0.0; ROWS.min(b - a) * w];
                for c in (a..b).step_by(ROWS) {
                    let m = ROWS.min(b - c);
                    let bytes = &mut bytes[..m * w * 8];
                    // The file was written by us and is not shared: a failed read is a broken
                    // machine (disk error), not bad input.
                    read_at(file, bytes, (c * w * 8) as u64).unwrap_or_else(|e| {
                        panic!("reading back a temporary file of this run: {e}")
                    });
                    for (v, b) in vals.iter_mut().zip(bytes.chunks_exact(8)) {
                        *v = f64::from_le_bytes(b.try_into().expect("8 bytes"));
                    }
                    vals[..m * w].chunks_exact(w).for_each(&mut f);
                }
            }
        }
    }
}

/// Largest gap, in mean sample periods, between a log's last sample and the first of a log that
/// goes on from it ([`Log::continues`]): a logger's jitter and a dropped sample or two, not a
/// pause between runs.
pub const CONTINUES_WITHIN: f64 = 3.0;

/// Samples of one data file, in memory or spilled to disk; cheap to clone and to slice.
#[derive(Debug, Clone)]
pub struct Log {
    /// Where it was read from (for error messages and reports).
    pub source: String,
    /// The recording its rows come from (its source; a [`Log::slice`] keeps its file's): one
    /// run, for effects that differ from run to run (`run_offset`).
    run: Arc<str>,
    /// Time from its run's start to its first sample (s), read by `drift`: 0 for a file of its
    /// own; a file that goes on where a training file stopped carries on that file's
    /// ([`Log::continuing`]). A [`Log::slice`] keeps its file's.
    run_time: f64,
    pub layout: RowLayout,
    /// This log's rows of the table: `lo..hi`.
    lo: usize,
    hi: usize,
    table: Arc<Table>,
}

impl From<Trajectory> for Log {
    fn from(t: Trajectory) -> Log {
        let layout = t.layout();
        let mut rows = Vec::with_capacity(t.len() * layout.width());
        let mut row = Vec::with_capacity(layout.width());
        for k in 0..t.len() {
            t.row_into(k, &mut row);
            rows.extend_from_slice(&row);
        }
        Log {
            run: t.source.as_str().into(),
            run_time: 0.0,
            source: t.source,
            layout,
            lo: 0,
            hi: t.t.len(),
            table: Arc::new(Table {
                width: layout.width(),
                rows: t.t.len(),
                store: Store::Memory(rows),
            }),
        }
    }
}

impl Log {
    /// Reads a CSV (or gzip-compressed CSV) file; with `dof = Some(n)` its header must match an
    /// `n`-joint arm. Spills to a temporary file beyond [`SPILL_ROWS`] rows.
    pub fn open(path: &Path, dof: Option<usize>) -> Result<Log, DataError> {
        Self::open_spilling(path, dof, SPILL_ROWS)
    }

    /// [`Log::open`] spilling beyond `spill_rows` rows (tests use a small value).
    pub fn open_spilling(
        path: &Path,
        dof: Option<usize>,
        spill_rows: usize,
    ) -> Result<Log, DataError> {
        let origin = path.display().to_string();
        let mut table: Option<TableWriter> = None;
        let (layout, rows) = data::read_rows(data::open(path)?, &origin, dof, &mut |l, row| {
            table
                .get_or_insert_with(|| TableWriter::new(l.width(), spill_rows))
                .push(row)
        })?;
        let table = table
            .expect("at least one row")
            .finish()
            .map_err(|e| DataError {
                loc: Location::file(&origin),
                kind: Box::new(DataErrorKind::TempFile(e)),
            })?;
        Ok(Log {
            run: origin.as_str().into(),
            run_time: 0.0,
            source: origin,
            layout,
            lo: 0,
            hi: rows,
            table: Arc::new(table),
        })
    }

    /// A log of the rows of `table` (written by a reader of another format, e.g. [`crate::bag`]),
    /// laid out as `layout` says.
    pub fn from_table(source: String, layout: RowLayout, table: Table) -> Log {
        debug_assert_eq!(layout.width(), table.width());
        Log {
            run: source.as_str().into(),
            run_time: 0.0,
            source,
            layout,
            lo: 0,
            hi: table.len(),
            table: Arc::new(table),
        }
    }

    /// The recording this log's rows come from (see the field).
    pub fn run(&self) -> &str {
        &self.run
    }

    /// Time from its run's start to its first sample (s; see the field).
    pub fn run_time(&self) -> f64 {
        self.run_time
    }

    /// The training log of `train` this one goes on from — its first sample after that log's
    /// last, within [`CONTINUES_WITHIN`] of that log's mean sample period — as one run: this
    /// log then has that log's run and its time since the run's start goes on (a run split by
    /// time into fit and holdout files, its time column kept). `None` when none does.
    pub fn continues<'a>(&self, train: &'a [Log]) -> Option<&'a Log> {
        if self.is_empty() {
            return None;
        }
        let t0 = self.t(0);
        train.iter().find(|l| {
            let n = l.len();
            if n < 2 {
                return false;
            }
            let (first, last) = (l.t(0), l.t(n - 1));
            let dt = (last - first) / (n - 1) as f64;
            t0 > last && t0 - last <= CONTINUES_WITHIN * dt
        })
    }

    /// This log as the rest of `earlier`'s run ([`Log::continues`]).
    pub fn continuing(mut self, earlier: &Log) -> Log {
        self.run_time = earlier.run_time + (self.t(0) - earlier.t(0));
        self.run = earlier.run.clone();
        self
    }

    /// The distinct recordings of `logs` ([`Log::run`]), in the order they first appear.
    pub fn runs<'a>(logs: impl IntoIterator<Item = &'a Log>) -> Vec<&'a str> {
        let mut out: Vec<&str> = Vec::new();
        for log in logs {
            if !out.contains(&log.run()) {
                out.push(log.run());
            }
        }
        out
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.hi - self.lo
    }

    pub fn is_empty(&self) -> bool {
        self.hi == self.lo
    }

    pub fn dof(&self) -> usize {
        self.layout.dof
    }

    /// Whether the log was spilled to a temporary file.
    pub fn spilled(&self) -> bool {
        self.table.spilled()
    }

    /// An identity for caches: the same table and first row.
    pub fn key(&self) -> (usize, usize) {
        (Arc::as_ptr(&self.table) as usize, self.lo)
    }

    /// Rows `lo..hi` as a log of their own, named `source[rows lo+1..hi]` (no copy).
    pub fn slice(&self, lo: usize, hi: usize) -> Log {
        let hi = hi.min(self.len());
        let lo = lo.min(hi);
        Log {
            source: format!("{}[rows {}..{}]", self.source, lo + 1, hi),
            run: self.run.clone(),
            run_time: self.run_time,
            layout: self.layout,
            lo: self.lo + lo,
            hi: self.lo + hi,
            table: self.table.clone(),
        }
    }

    /// This log with its torque multiplied by `scale[j]` per joint (drives that log current:
    /// `torque = gain × current`); a copy, spilled as the original would be.
    pub fn scale_torque(&self, scale: &[f64]) -> Result<Log, DataError> {
        let Some(off) = self.layout.tau_offset() else {
            return Ok(self.clone());
        };
        let mut w = TableWriter::new(self.layout.width(), SPILL_ROWS);
        let mut buf = Vec::with_capacity(self.layout.width());
        let mut res = Ok(());
        self.rows(0, self.len(), |row| {
            if res.is_err() {
                return;
            }
            buf.clear();
            buf.extend_from_slice(row);
            for (x, s) in buf[off..].iter_mut().zip(scale) {
                *x *= s;
            }
            res = w.push(&buf);
        });
        let temp = |e: std::io::Error| DataError {
            loc: Location::file(&self.source),
            kind: Box::new(DataErrorKind::TempFile(e)),
        };
        res.map_err(temp)?;
        let table = w.finish().map_err(temp)?;
        Ok(Log {
            run: self.run.clone(),
            run_time: self.run_time,
            ..Log::from_table(self.source.clone(), self.layout, table)
        })
    }

    /// Calls `f` with each of rows `r0..r1` in turn (the canonical row, see [`RowLayout`]).
    pub fn rows(&self, r0: usize, r1: usize, f: impl FnMut(&[f64])) {
        let r1 = r1.min(self.len());
        self.table.rows(self.lo + r0.min(r1), self.lo + r1, f);
    }

    /// Rows `r0..r1` as a trajectory (row-major blocks, named like the log).
    pub fn read(&self, r0: usize, r1: usize) -> Trajectory {
        let m = r1.min(self.len()).saturating_sub(r0);
        let mut t = Trajectory::empty(&self.source, &self.layout, m);
        self.rows(r0, r1, |row| t.push_row(row));
        t
    }

    /// Time of sample `r`.
    pub fn t(&self, r: usize) -> f64 {
        let mut t = f64::NAN;
        self.rows(r, r + 1, |row| t = row[0]);
        t
    }

    /// First sample `r` for which `pred(t(r))` is false (`pred` true on a prefix), as
    /// [`slice::partition_point`].
    pub fn partition_point(&self, pred: impl Fn(f64) -> bool) -> usize {
        let (mut lo, mut hi) = (0, self.len());
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if pred(self.t(mid)) {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        lo
    }

    /// Error unless there are at least `needed` samples.
    pub fn require_samples(&self, needed: usize, purpose: &str) -> Result<(), DataError> {
        if self.len() < needed {
            return Err(DataError {
                loc: Location::file(&self.source),
                kind: Box::new(DataErrorKind::TooFewSamples {
                    found: self.len(),
                    needed,
                    purpose: purpose.to_string(),
                }),
            });
        }
        Ok(())
    }
}

fn write_f64s(w: &mut impl Write, values: &[f64]) -> std::io::Result<()> {
    for v in values {
        w.write_all(&v.to_le_bytes())?;
    }
    Ok(())
}

#[cfg(unix)]
fn read_at(f: &File, buf: &mut [u8], offset: u64) -> std::io::Result<()> {
    std::os::unix::fs::FileExt::read_exact_at(f, buf, offset)
}

#[cfg(windows)]
fn read_at(f: &File, mut buf: &mut [u8], mut offset: u64) -> std::io::Result<()> {
    while !buf.is_empty() {
        match std::os::windows::fs::FileExt::seek_read(f, buf, offset)? {
            0 => return Err(std::io::ErrorKind::UnexpectedEof.into()),
            k => {
                buf = &mut buf[k..];
                offset += k as u64;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn csv(rows: usize) -> String {
        let mut s = String::from("t,q1,q2,tau2,tau1,dq1,dq2\n");
        for k in 0..rows {
            let t = k as f64 * 0.01;
            s += &format!(
                "{t},{},{},{},{},{},{}\n",
                t.sin(),
                t.cos(),
                2.0 * t,
                -t,
                t.cos(),
                -t.sin()
            );
        }
        s
    }

    #[test]
    fn spilled_and_held_logs_read_the_same_windows_as_the_loaded_trajectory() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.csv");
        std::fs::write(&path, csv(1000)).unwrap();
        let whole = Trajectory::from_path(&path, Some(2)).unwrap();
        let held = Log::open(&path, Some(2)).unwrap();
        let spilled = Log::open_spilling(&path, Some(2), 64).unwrap();
        assert!(!held.spilled() && spilled.spilled());
        for log in [&held, &spilled, &Log::from(whole.clone())] {
            assert_eq!(log.len(), 1000);
            assert_eq!(log.read(0, 1000), whole);
            let mut part = whole.slice(130, 517);
            part.source = whole.source.clone();
            assert_eq!(log.read(130, 517), part);
            assert_eq!(log.t(999), whole.t[999]);
            assert_eq!(log.partition_point(|t| t < 5.0), 500);
            let s = log.slice(100, 300);
            assert_eq!(s.len(), 200);
            assert_eq!(s.t(0), whole.t[100]);
            assert_eq!(s.read(10, 20).tau, whole.slice(110, 120).tau);
        }
    }
}
