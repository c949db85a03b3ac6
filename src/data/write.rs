//! Trajectories as CSV: the header and rows every command writes, each number in its shortest
//! form that reads back to the same `f64`.

use std::io::Write;

use super::{header, Trajectory};

impl Trajectory {
    /// Writes the trajectory as CSV with the canonical header (only the blocks present).
    pub fn write_csv(&self, w: &mut dyn Write) -> std::io::Result<()> {
        let h = header(
            self.dof,
            self.dq.is_some(),
            self.ddq.is_some(),
            self.tau.is_some(),
        );
        let mut row = Vec::with_capacity(h.len());
        write_header(w, &h)?;
        for k in 0..self.len() {
            self.row_into(k, &mut row);
            write_row(w, &row)?;
        }
        Ok(())
    }
}

/// Writes a CSV header line.
pub fn write_header(w: &mut dyn Write, names: &[String]) -> std::io::Result<()> {
    writeln!(w, "{}", names.join(","))
}

/// Writes one CSV row of numbers, each in its shortest exactly-round-tripping form.
pub fn write_row(w: &mut dyn Write, values: &[f64]) -> std::io::Result<()> {
    for (i, v) in values.iter().enumerate() {
        if i > 0 {
            w.write_all(b",")?;
        }
        // `{}` never uses an exponent (1e-300 would print 300 digits); `{:e}` is ugly for
        // everyday magnitudes. Both are shortest round-trip representations.
        let a = v.abs();
        if a == 0.0 || (1e-5..1e16).contains(&a) {
            write!(w, "{v}")?;
        } else {
            write!(w, "{v:e}")?;
        }
    }
    w.write_all(b"\n")
}
