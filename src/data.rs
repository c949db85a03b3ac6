//! Trajectory CSV files: `t,q1..qn[,dq1..dqn][,ddq1..ddqn][,tau1..taun]` (SI units), plain or
//! gzip-compressed (detected by its magic bytes, so `.csv.gz` and misnamed files both work).
//!
//! Columns are matched by name (case and surrounding spaces ignored), so their order does not
//! matter; each of the `dq`, `ddq`, `tau` blocks is all-or-nothing. Accepted quirks of real
//! exports: CRLF line ends, no final newline, scientific notation, a UTF-8 byte-order mark,
//! blank lines and `#` comment lines. Rejected, with file, line and column: missing, extra,
//! duplicate or misnamed columns, non-numeric or empty cells, NaN/inf, short or long rows, empty
//! files, header only, time that repeats or goes backwards, corrupt gzip.
//!
//! Samples are stored row-major in flat vectors (`q[k * dof + j]`): one allocation per block,
//! cache-friendly for the per-sample kernels.
//!
//! ```
//! use dynid::data::Trajectory;
//! let csv = "t,q1,dq1,ddq1\n0.0,0.1,0,0\n0.01,0.2,1e1,0\n";
//! let traj = Trajectory::from_reader(csv.as_bytes(), "log.csv", Some(1))?;
//! assert_eq!(traj.len(), 2);
//! assert_eq!(traj.dq_at(1), Some(&[10.0][..]));
//! # Ok::<(), dynid::data::DataError>(())
//! ```

use std::fmt;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use rayon::prelude::*;

use crate::diag::{did_you_mean, Location};

mod columns;
mod write;

pub use write::{write_header, write_row};

/// A sampled trajectory; `q`, `dq`, `ddq`, `tau` are row-major (`len() × dof`).
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Where it was read from (for error messages), e.g. the path.
    pub source: String,
    pub dof: usize,
    pub t: Vec<f64>,
    pub q: Vec<f64>,
    pub dq: Option<Vec<f64>>,
    pub ddq: Option<Vec<f64>>,
    pub tau: Option<Vec<f64>>,
}

/// A trajectory file that cannot be used, with where and how to fix it.
#[derive(Debug, thiserror::Error)]
#[error("{loc}: {kind}")]
pub struct DataError {
    pub loc: Location,
    /// Boxed: errors travel through `Result`s of hot-ish loader code; keep them small.
    pub kind: Box<DataErrorKind>,
}

/// What is wrong with a trajectory file.
#[derive(Debug)]
pub enum DataErrorKind {
    Io(std::io::Error),
    /// The gzip stream is corrupt or truncated.
    Gzip(std::io::Error),
    /// The temporary copy of a long file could not be written (see [`crate::log`]).
    TempFile(std::io::Error),
    Empty {
        expected: String,
    },
    HeaderOnly,
    EmptyColumnName {
        expected: String,
    },
    MisnamedColumn {
        name: String,
        suggestion: Option<String>,
        expected: String,
    },
    DuplicateColumn {
        name: String,
    },
    /// A column for a joint the arm does not have.
    ExtraColumn {
        name: String,
        dof: usize,
        expected: String,
    },
    MissingColumn {
        name: String,
        expected: String,
    },
    /// A block needed by the caller (e.g. `dq` for inverse dynamics) is absent.
    MissingBlock {
        block: &'static str,
        purpose: String,
        expected: String,
    },
    FieldCount {
        found: usize,
        expected: usize,
    },
    EmptyCell,
    NotANumber {
        cell: String,
    },
    NonFinite {
        cell: String,
    },
    TimeNotIncreasing {
        previous: f64,
        current: f64,
    },
    TooFewSamples {
        found: usize,
        needed: usize,
        purpose: String,
    },
}

impl fmt::Display for DataErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use DataErrorKind::*;
        match self {
            Io(e) => write!(f, "cannot read the file: {e} — check the path and permissions"),
            Gzip(e) => write!(f, "corrupt or truncated gzip data: {e} — re-export or re-compress the file (`gzip -t` checks it)"),
            TempFile(e) => write!(f, "cannot write the temporary copy of this long file: {e} — free space in the temporary directory or point TMPDIR elsewhere"),
            Empty { expected } => write!(f, "the file is empty — expected a header line with columns {expected}, then one row per sample"),
            HeaderOnly => write!(f, "the file has a header but no data rows — add at least one sample row"),
            EmptyColumnName { expected } => write!(f, "empty column name (a trailing comma?) — expected columns {expected}"),
            MisnamedColumn { name, suggestion, expected } => {
                write!(f, "unknown column `{name}` — ")?;
                if let Some(s) = suggestion {
                    write!(f, "did you mean `{s}`? ")?;
                }
                write!(f, "expected columns {expected}")
            }
            DuplicateColumn { name } => write!(f, "column `{name}` appears twice — remove one of them"),
            ExtraColumn { name, dof, expected } => write!(
                f,
                "extra column `{name}`: the arm has {dof} joints — expected columns {expected} (wrong arm or wrong file?)"
            ),
            MissingColumn { name, expected } => write!(f, "missing column `{name}` — expected columns {expected}"),
            MissingBlock { block, purpose, expected } => write!(
                f,
                "no `{block}` columns, needed for {purpose} — add them (expected columns {expected})"
            ),
            FieldCount { found, expected } => write!(
                f,
                "row has {found} fields but the header has {expected} — every row needs one value per column"
            ),
            EmptyCell => write!(f, "empty cell — every cell needs a number"),
            NotANumber { cell } => write!(f, "`{cell}` is not a number — use plain decimal or scientific notation (e.g. 1.5e-3), `.` as decimal separator"),
            NonFinite { cell } => write!(f, "`{cell}` is not a finite number — remove or interpolate the sample"),
            TimeNotIncreasing { previous, current } => write!(
                f,
                "t = {current} does not increase (previous sample t = {previous}) — samples must be in time order without repeats"
            ),
            TooFewSamples { found, needed, purpose } => write!(
                f,
                "{found} samples, at least {needed} are needed for {purpose} — record a longer trajectory"
            ),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Block {
    Q,
    Dq,
    Ddq,
    Tau,
}

impl Block {
    const ALL: [Block; 4] = [Block::Q, Block::Dq, Block::Ddq, Block::Tau];
    fn prefix(self) -> &'static str {
        match self {
            Block::Q => "q",
            Block::Dq => "dq",
            Block::Ddq => "ddq",
            Block::Tau => "tau",
        }
    }
}

/// Human-readable list of the columns a file for `dof` joints may have.
pub fn expected_columns(dof: usize) -> String {
    format!("t, q1..q{dof}, then optionally dq1..dq{dof}, ddq1..ddq{dof}, and tau1..tau{dof}")
}

/// Canonical header for the given blocks: `t,q1..,dq1..,ddq1..,tau1..`.
pub fn header(dof: usize, dq: bool, ddq: bool, tau: bool) -> Vec<String> {
    let mut h = vec!["t".to_string()];
    for (block, present) in Block::ALL.iter().zip([true, dq, ddq, tau]) {
        if present {
            h.extend((1..=dof).map(|j| format!("{}{j}", block.prefix())));
        }
    }
    h
}

/// Where each block's columns are in the file.
struct Columns {
    dof: usize,
    t: usize,
    blocks: [Option<Vec<usize>>; 4],
    names: Vec<String>,
}

fn parse_name(name: &str) -> Option<(Option<Block>, usize)> {
    if name == "t" {
        return Some((None, 0));
    }
    // Longest prefix first: `ddq` before `dq` before `q`.
    for block in [Block::Ddq, Block::Dq, Block::Tau, Block::Q] {
        if let Some(idx) = name.strip_prefix(block.prefix()) {
            if !idx.is_empty() && idx.bytes().all(|b| b.is_ascii_digit()) && !idx.starts_with('0') {
                return idx.parse().ok().map(|i| (Some(block), i));
            }
        }
    }
    None
}

impl Columns {
    fn from_header(
        names: Vec<String>,
        want_dof: Option<usize>,
        file: &str,
        line: usize,
    ) -> Result<Columns, DataError> {
        let loc = |field: &str| Location {
            file: file.to_string(),
            line: Some(line),
            field: Some(field.to_string()),
        };
        let parsed: Vec<_> = names.iter().map(|n| parse_name(n)).collect();
        let dof = want_dof.unwrap_or_else(|| {
            parsed
                .iter()
                .filter_map(|p| match p {
                    Some((Some(Block::Q), i)) => Some(*i),
                    _ => None,
                })
                .max()
                .unwrap_or(0)
        });
        let expected = if dof == 0 {
            "t, q1..qn, then optionally dq1..dqn, ddq1..ddqn, tau1..taun".to_string()
        } else {
            expected_columns(dof)
        };
        let canonical = header(dof.max(1), true, true, true);
        let mut t = None;
        let mut slots: [Vec<Option<usize>>; 4] = std::array::from_fn(|_| vec![None; dof]);
        for (col, (name, p)) in names.iter().zip(&parsed).enumerate() {
            let err = |kind| {
                Err(DataError {
                    loc: loc(name),
                    kind: Box::new(kind),
                })
            };
            match *p {
                _ if name.is_empty() => {
                    return Err(DataError {
                        loc: loc(&format!("column {}", col + 1)),
                        kind: Box::new(DataErrorKind::EmptyColumnName { expected }),
                    })
                }
                None => {
                    let cands: Vec<&str> = canonical.iter().map(String::as_str).collect();
                    let suggestion = did_you_mean(name, &cands).map(str::to_string);
                    return err(DataErrorKind::MisnamedColumn {
                        name: name.clone(),
                        suggestion,
                        expected,
                    });
                }
                Some((None, _)) => {
                    if t.replace(col).is_some() {
                        return err(DataErrorKind::DuplicateColumn { name: name.clone() });
                    }
                }
                Some((Some(block), i)) => {
                    if i > dof {
                        return err(DataErrorKind::ExtraColumn {
                            name: name.clone(),
                            dof,
                            expected,
                        });
                    }
                    if slots[block as usize][i - 1].replace(col).is_some() {
                        return err(DataErrorKind::DuplicateColumn { name: name.clone() });
                    }
                }
            }
        }
        let missing = |name: String| DataError {
            loc: Location {
                file: file.to_string(),
                line: Some(line),
                field: None,
            },
            kind: Box::new(DataErrorKind::MissingColumn {
                name,
                expected: expected.clone(),
            }),
        };
        let t = t.ok_or_else(|| missing("t".to_string()))?;
        if dof == 0 {
            return Err(missing("q1".to_string()));
        }
        let mut blocks: [Option<Vec<usize>>; 4] = Default::default();
        for block in Block::ALL {
            let s = &slots[block as usize];
            let present = s.iter().any(Option::is_some);
            if !present && block != Block::Q {
                continue;
            }
            if let Some(j) = s.iter().position(Option::is_none) {
                return Err(missing(format!("{}{}", block.prefix(), j + 1)));
            }
            blocks[block as usize] = Some(s.iter().flatten().copied().collect());
        }
        Ok(Columns {
            dof,
            t,
            blocks,
            names,
        })
    }
}

impl Columns {
    /// The blocks the columns carry.
    fn layout(&self) -> RowLayout {
        RowLayout {
            dof: self.dof,
            dq: self.blocks[Block::Dq as usize].is_some(),
            ddq: self.blocks[Block::Ddq as usize].is_some(),
            tau: self.blocks[Block::Tau as usize].is_some(),
        }
    }

    /// The columns in the canonical row order (`t, q.., [dq..], [ddq..], [tau..]`).
    fn order(&self) -> Vec<usize> {
        std::iter::once(self.t)
            .chain(self.blocks.iter().flatten().flatten().copied())
            .collect()
    }
}

const GZIP_MAGIC: [u8; 2] = [0x1f, 0x8b];

/// Opens `path` for reading, an error naming it if that fails.
pub fn open(path: &Path) -> Result<std::fs::File, DataError> {
    std::fs::File::open(path).map_err(|e| DataError {
        loc: Location::file(path.display().to_string()),
        kind: Box::new(DataErrorKind::Io(e)),
    })
}

/// Which blocks a file's rows carry. [`read_rows`] hands every row over in the canonical order
/// `t, q1..qn, [dq1..dqn], [ddq1..ddqn], [tau1..taun]`, whatever the file's column order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RowLayout {
    pub dof: usize,
    pub dq: bool,
    pub ddq: bool,
    pub tau: bool,
}

impl RowLayout {
    /// Values per row.
    pub fn width(&self) -> usize {
        1 + self.dof * (1 + usize::from(self.dq) + usize::from(self.ddq) + usize::from(self.tau))
    }

    /// Where a row's τ block starts (`None` without one).
    pub fn tau_offset(&self) -> Option<usize> {
        self.tau
            .then(|| 1 + self.dof * (1 + usize::from(self.dq) + usize::from(self.ddq)))
    }
}

/// Streams a CSV (or gzip-compressed CSV) source row by row into `sink`, checking every cell as
/// [`Trajectory::from_reader`] does; returns the layout and the number of rows. Nothing but the
/// current row is held, so a log of any length reads in constant memory. `sink` errors are
/// reported as failures to write a temporary copy of `origin` (what the sinks that can fail do).
pub fn read_rows<R: Read>(
    reader: R,
    origin: &str,
    dof: Option<usize>,
    sink: &mut dyn FnMut(&RowLayout, &[f64]) -> std::io::Result<()>,
) -> Result<(RowLayout, usize), DataError> {
    let io_err = |e| DataError {
        loc: Location::file(origin),
        kind: Box::new(DataErrorKind::Io(e)),
    };
    let mut buf = BufReader::new(reader);
    let head = buf.fill_buf().map_err(io_err)?;
    if !head.starts_with(&GZIP_MAGIC) {
        return parse(buf, origin, dof, false, sink);
    }
    let mut gz = flate2::bufread::MultiGzDecoder::new(buf);
    let gzip_err = |e| DataError {
        loc: Location::file(origin),
        kind: Box::new(DataErrorKind::Gzip(e)),
    };
    match parse(&mut gz, origin, dof, true, sink) {
        Ok(r) => Ok(r),
        // A corrupt stream may decode to garbage before its checksum fails at the end: report
        // it as corrupt, not as whatever the garbage looked like.
        Err(e) if !matches!(*e.kind, DataErrorKind::Gzip(_)) => {
            match std::io::copy(&mut gz, &mut std::io::sink()) {
                Err(g) => Err(gzip_err(g)),
                Ok(_) => Err(e),
            }
        }
        Err(e) => Err(e),
    }
}

impl Trajectory {
    /// Reads a CSV (or gzip-compressed CSV) file. With `dof = Some(n)` the header must match an
    /// `n`-joint arm; with `None` the DOF is taken from the `q` columns.
    pub fn from_path(path: &Path, dof: Option<usize>) -> Result<Self, DataError> {
        let file = path.display().to_string();
        Self::from_reader(open(path)?, &file, dof)
    }

    /// Reads CSV (or gzip-compressed CSV) from any reader; `origin` names it in errors.
    pub fn from_reader<R: Read>(
        reader: R,
        origin: &str,
        dof: Option<usize>,
    ) -> Result<Self, DataError> {
        let mut traj: Option<Trajectory> = None;
        read_rows(reader, origin, dof, &mut |l, row| {
            traj.get_or_insert_with(|| Trajectory::empty(origin, l, 0))
                .push_row(row);
            Ok(())
        })?;
        Ok(traj.expect("read_rows rejects a file without rows"))
    }

    /// No samples yet, with the blocks of `layout` (room for `capacity` samples).
    pub fn empty(source: &str, layout: &RowLayout, capacity: usize) -> Trajectory {
        let n = layout.dof;
        let block = |present: bool| present.then(|| Vec::with_capacity(capacity * n));
        Trajectory {
            source: source.to_string(),
            dof: n,
            t: Vec::with_capacity(capacity),
            q: Vec::with_capacity(capacity * n),
            dq: block(layout.dq),
            ddq: block(layout.ddq),
            tau: block(layout.tau),
        }
    }

    /// Appends one sample given as a canonical row (`t, q.., [dq..], [ddq..], [tau..]` for the
    /// blocks this trajectory has).
    pub fn push_row(&mut self, row: &[f64]) {
        let n = self.dof;
        self.t.push(row[0]);
        self.q.extend_from_slice(&row[1..1 + n]);
        let mut at = 1 + n;
        for b in [&mut self.dq, &mut self.ddq, &mut self.tau]
            .into_iter()
            .flatten()
        {
            b.extend_from_slice(&row[at..at + n]);
            at += n;
        }
    }

    /// Sample `k` as a canonical row (the inverse of [`Trajectory::push_row`]), into `row`.
    pub fn row_into(&self, k: usize, row: &mut Vec<f64>) {
        row.clear();
        row.push(self.t[k]);
        row.extend_from_slice(self.q_at(k));
        for b in [self.dq_at(k), self.ddq_at(k), self.tau_at(k)]
            .into_iter()
            .flatten()
        {
            row.extend_from_slice(b);
        }
    }

    /// The blocks this trajectory has.
    pub fn layout(&self) -> RowLayout {
        RowLayout {
            dof: self.dof,
            dq: self.dq.is_some(),
            ddq: self.ddq.is_some(),
            tau: self.tau.is_some(),
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Joint positions of sample `k`.
    pub fn q_at(&self, k: usize) -> &[f64] {
        &self.q[k * self.dof..(k + 1) * self.dof]
    }

    /// Joint velocities of sample `k`, if the file had them.
    pub fn dq_at(&self, k: usize) -> Option<&[f64]> {
        self.dq
            .as_ref()
            .map(|v| &v[k * self.dof..(k + 1) * self.dof])
    }

    /// Joint accelerations of sample `k`, if the file had them.
    pub fn ddq_at(&self, k: usize) -> Option<&[f64]> {
        self.ddq
            .as_ref()
            .map(|v| &v[k * self.dof..(k + 1) * self.dof])
    }

    /// Joint torques of sample `k`, if the file had them.
    pub fn tau_at(&self, k: usize) -> Option<&[f64]> {
        self.tau
            .as_ref()
            .map(|v| &v[k * self.dof..(k + 1) * self.dof])
    }

    /// Error unless the blocks needed for `purpose` are present.
    pub fn require(&self, dq: bool, ddq: bool, tau: bool, purpose: &str) -> Result<(), DataError> {
        let checks = [
            (dq, self.dq.is_some(), "dq"),
            (ddq, self.ddq.is_some(), "ddq"),
            (tau, self.tau.is_some(), "tau"),
        ];
        for (needed, present, block) in checks {
            if needed && !present {
                return Err(DataError {
                    loc: Location::file(&self.source),
                    kind: Box::new(DataErrorKind::MissingBlock {
                        block,
                        purpose: purpose.to_string(),
                        expected: expected_columns(self.dof),
                    }),
                });
            }
        }
        Ok(())
    }

    /// Samples `lo..hi` as a trajectory of their own, named `source[rows lo+1..hi]`.
    pub fn slice(&self, lo: usize, hi: usize) -> Trajectory {
        let hi = hi.min(self.len());
        let lo = lo.min(hi);
        let n = self.dof;
        let cut = |v: &Vec<f64>| v[lo * n..hi * n].to_vec();
        Trajectory {
            source: format!("{}[rows {}..{}]", self.source, lo + 1, hi),
            dof: n,
            t: self.t[lo..hi].to_vec(),
            q: cut(&self.q),
            dq: self.dq.as_ref().map(cut),
            ddq: self.ddq.as_ref().map(cut),
            tau: self.tau.as_ref().map(cut),
        }
    }
}

/// A CSV reader error as a located data error (`last_line`: the last line read, for errors
/// without a position). With `gzip`, read errors come from the decoder: the stream is corrupt.
fn csv_error(e: csv::Error, file: &str, last_line: usize, gzip: bool) -> DataError {
    let line = e
        .position()
        .map(|p| p.line() as usize)
        .or(Some(last_line + 1));
    let loc = Location {
        file: file.to_string(),
        line,
        field: None,
    };
    let kind = match e.into_kind() {
        csv::ErrorKind::Io(io) if gzip => {
            return DataError {
                loc: Location::file(file),
                kind: Box::new(DataErrorKind::Gzip(io)),
            }
        }
        csv::ErrorKind::Io(io) => DataErrorKind::Io(io),
        csv::ErrorKind::Utf8 { err, .. } => DataErrorKind::NotANumber {
            cell: format!("invalid UTF-8 ({err})"),
        },
        other => DataErrorKind::Io(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("{other:?}"),
        )),
    };
    DataError {
        loc,
        kind: Box::new(kind),
    }
}

/// One cell as a finite number, or what is wrong with it.
fn parse_cell(raw: &[u8]) -> Result<f64, DataErrorKind> {
    let text = std::str::from_utf8(raw).map_err(|_| DataErrorKind::NotANumber {
        cell: String::from_utf8_lossy(raw).into_owned(),
    })?;
    let text = text.trim();
    if text.is_empty() {
        return Err(DataErrorKind::EmptyCell);
    }
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(DataErrorKind::NonFinite {
            cell: text.to_string(),
        }),
        Err(_) => Err(DataErrorKind::NotANumber {
            cell: text.to_string(),
        }),
    }
}

/// A header cell as a column name: spaces and a byte-order mark dropped, lower case.
fn column_name(raw: &str) -> String {
    raw.trim()
        .trim_start_matches('\u{feff}')
        .trim()
        .to_ascii_lowercase()
}

/// The header record: the file's columns checked against the arm (`want_dof`), and its line.
fn read_header<R: Read>(
    rdr: &mut csv::Reader<R>,
    record: &mut csv::ByteRecord,
    file: &str,
    want_dof: Option<usize>,
    gzip: bool,
) -> Result<(Columns, usize), DataError> {
    let got = rdr
        .read_byte_record(record)
        .map_err(|e| csv_error(e, file, 0, gzip))?;
    if !got {
        let expected = want_dof.map_or_else(|| "t, q1..qn, ...".to_string(), expected_columns);
        return Err(DataError {
            loc: Location::file(file),
            kind: Box::new(DataErrorKind::Empty { expected }),
        });
    }
    let header_line = record.position().map_or(1, |p| p.line() as usize);
    let names: Vec<String> = record
        .iter()
        .map(|f| column_name(&String::from_utf8_lossy(f)))
        .collect();
    let cols = Columns::from_header(names, want_dof, file, header_line)?;
    Ok((cols, header_line))
}

/// Records per batch of [`parse`].
const BATCH: usize = 8192;

/// Records read but not yet handed over, with each one's line, parsed cells and verdict.
#[derive(Default)]
struct Batch {
    records: Vec<csv::ByteRecord>,
    lines: Vec<usize>,
    len: usize,
    /// Row `i`'s cells in the canonical order: `values[i * width..]`.
    values: Vec<f64>,
    status: Vec<Parsed>,
    /// What stopped the reading after the `len` records (the file's last word).
    err: Option<DataError>,
}

/// One record's cells checked on their own (the time order is checked in sequence).
enum Parsed {
    Row(f64),
    FieldCount(usize),
    BadTime(DataErrorKind),
    BadCell {
        t: f64,
        col: usize,
        kind: DataErrorKind,
    },
}

impl Batch {
    /// Reads up to [`BATCH`] records (fewer at the end of the input or at an error).
    fn read<R: Read>(
        &mut self,
        rdr: &mut csv::Reader<R>,
        last_line: &mut usize,
        file: &str,
        gzip: bool,
    ) {
        self.len = 0;
        while self.len < BATCH {
            if self.records.len() == self.len {
                self.records.push(csv::ByteRecord::new());
                self.lines.push(0);
            }
            match rdr.read_byte_record(&mut self.records[self.len]) {
                Ok(true) => {}
                Ok(false) => break,
                Err(e) => {
                    self.err = Some(csv_error(e, file, *last_line, gzip));
                    break;
                }
            }
            let line = self.records[self.len]
                .position()
                .map_or(*last_line + 1, |p| p.line() as usize);
            (*last_line, self.lines[self.len]) = (line, line);
            self.len += 1;
        }
    }

    /// Parses every record's cells, in parallel.
    fn parse(&mut self, cols: &Columns, order: &[usize], width: usize) {
        let n = self.len;
        self.values.resize(n * width, 0.0);
        self.status.resize_with(n, || Parsed::Row(0.0));
        self.records[..n]
            .par_iter()
            .zip(self.values.par_chunks_mut(width))
            .zip(&mut self.status[..n])
            .with_min_len(512)
            .for_each(|((rec, row), st)| *st = parse_record(rec, cols, order, row));
    }
}

/// A record's cells into `row` (canonical order), or what is wrong with them, in the order a
/// reader meets it: the field count, the time, then the cells left to right.
fn parse_record(rec: &csv::ByteRecord, cols: &Columns, order: &[usize], row: &mut [f64]) -> Parsed {
    if rec.len() != cols.names.len() {
        return Parsed::FieldCount(rec.len());
    }
    let t = match parse_cell(&rec[cols.t]) {
        Ok(t) => t,
        Err(kind) => return Parsed::BadTime(kind),
    };
    for (v, &col) in row.iter_mut().zip(order) {
        match parse_cell(&rec[col]) {
            Ok(x) => *v = x,
            Err(kind) => return Parsed::BadCell { t, col, kind },
        }
    }
    Parsed::Row(t)
}

fn parse<R: Read>(
    reader: R,
    file: &str,
    want_dof: Option<usize>,
    gzip: bool,
    sink: &mut dyn FnMut(&RowLayout, &[f64]) -> std::io::Result<()>,
) -> Result<(RowLayout, usize), DataError> {
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .comment(Some(b'#'))
        .from_reader(reader);
    let mut record = csv::ByteRecord::new();
    let (cols, header_line) = read_header(&mut rdr, &mut record, file, want_dof, gzip)?;
    let mut last_line = header_line;
    let (layout, order) = (cols.layout(), cols.order());
    let width = layout.width();
    let mut check = RowCheck::new(file, &cols, layout);
    // Records are read a batch at a time; a batch's cells are parsed on rayon's threads while
    // this one reads the next, then its rows are checked and handed over in order (so the first
    // error in the file is the one reported, as row by row).
    let (mut cur, mut next) = (Batch::default(), Batch::default());
    cur.read(&mut rdr, &mut last_line, file, gzip);
    while cur.len > 0 || cur.err.is_some() {
        let more = cur.err.is_none() && cur.len == BATCH;
        rayon::in_place_scope(|s| {
            s.spawn(|_| cur.parse(&cols, &order, width));
            if more {
                next.read(&mut rdr, &mut last_line, file, gzip);
            }
        });
        for i in 0..cur.len {
            let parsed = std::mem::replace(&mut cur.status[i], Parsed::Row(0.0));
            let row = &cur.values[i * width..(i + 1) * width];
            check.row(cur.lines[i], parsed, row, sink)?;
        }
        if let Some(e) = cur.err.take() {
            return Err(e);
        }
        std::mem::swap(&mut cur, &mut next);
        next.len = 0;
    }
    check.finish()
}

/// The checks of a row in sequence (the field count, the time and its order, then the cells),
/// and the hand-over of the good ones: shared by the CSV reader and [`Trajectory::from_columns`]
/// so that both say the same about the same row.
struct RowCheck<'a> {
    file: &'a str,
    cols: &'a Columns,
    layout: RowLayout,
    rows: usize,
    prev: f64,
}

impl<'a> RowCheck<'a> {
    fn new(file: &'a str, cols: &'a Columns, layout: RowLayout) -> Self {
        RowCheck {
            file,
            cols,
            layout,
            rows: 0,
            prev: f64::NEG_INFINITY,
        }
    }

    /// Row `parsed` (its cells in `values`, canonical order) read from `line`: handed to `sink`,
    /// or the first thing wrong with it.
    fn row(
        &mut self,
        line: usize,
        parsed: Parsed,
        values: &[f64],
        sink: &mut dyn FnMut(&RowLayout, &[f64]) -> std::io::Result<()>,
    ) -> Result<(), DataError> {
        let (file, cols) = (self.file, self.cols);
        let at = |col: Option<usize>, kind| DataError {
            loc: Location {
                file: file.to_string(),
                line: Some(line),
                field: col.map(|c| cols.names[c].clone()),
            },
            kind: Box::new(kind),
        };
        let (tk, bad) = match parsed {
            Parsed::FieldCount(found) => {
                let expected = cols.names.len();
                return Err(at(None, DataErrorKind::FieldCount { found, expected }));
            }
            Parsed::BadTime(kind) => return Err(at(Some(cols.t), kind)),
            Parsed::Row(tk) => (tk, None),
            Parsed::BadCell { t, col, kind } => (t, Some((col, kind))),
        };
        if self.rows > 0 && tk <= self.prev {
            let (previous, current) = (self.prev, tk);
            return Err(at(
                Some(cols.t),
                DataErrorKind::TimeNotIncreasing { previous, current },
            ));
        }
        if let Some((col, kind)) = bad {
            return Err(at(Some(col), kind));
        }
        sink(&self.layout, values).map_err(|e| DataError {
            loc: Location::file(file),
            kind: Box::new(DataErrorKind::TempFile(e)),
        })?;
        (self.rows, self.prev) = (self.rows + 1, tk);
        Ok(())
    }

    /// The layout and the number of rows; an error when there were none.
    fn finish(self) -> Result<(RowLayout, usize), DataError> {
        if self.rows == 0 {
            return Err(DataError {
                loc: Location::file(self.file),
                kind: Box::new(DataErrorKind::HeaderOnly),
            });
        }
        Ok((self.layout, self.rows))
    }
}
