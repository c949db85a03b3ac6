//! A trajectory from named columns and a row-major block of numbers (what the Python bindings
//! hand over for an array or a DataFrame), with the CSV reader's checks and messages: the
//! header and each row are judged as if they were that CSV's text, a row named by its line
//! there (line 1 the header, row `i` line `i + 2`) and a cell by its column's name.

use super::{
    column_name, Columns, DataError, DataErrorKind, Location, Parsed, RowCheck, Trajectory,
};

impl Trajectory {
    /// `values` (`rows × names.len()`, row-major) under the column names `names`; `origin`
    /// names it in errors. With `dof = Some(n)` the columns must be an `n`-joint arm's, as for
    /// [`Trajectory::from_reader`], which says the same about the same table written as CSV.
    pub fn from_columns(
        origin: &str,
        names: &[String],
        values: &[f64],
        dof: Option<usize>,
    ) -> Result<Trajectory, DataError> {
        if names.is_empty() {
            let expected =
                dof.map_or_else(|| "t, q1..qn, ...".to_string(), super::expected_columns);
            return Err(DataError {
                loc: Location::file(origin),
                kind: Box::new(DataErrorKind::Empty { expected }),
            });
        }
        let names: Vec<String> = names.iter().map(|n| column_name(n)).collect();
        let cols = Columns::from_header(names, dof, origin, 1)?;
        let (layout, order) = (cols.layout(), cols.order());
        let width = cols.names.len();
        let rows = values.len().div_ceil(width);
        let mut traj = Trajectory::empty(origin, &layout, rows);
        let mut check = RowCheck::new(origin, &cols, layout);
        let mut row = vec![0.0; order.len()];
        for (i, cells) in values.chunks(width).enumerate() {
            let parsed = parse_row(cells, &cols, &order, &mut row);
            check.row(i + 2, parsed, &row, &mut |_, r| {
                traj.push_row(r);
                Ok(())
            })?;
        }
        check.finish()?;
        Ok(traj)
    }
}

/// One row's cells into `row` (canonical order), or what is wrong with them, in the order the
/// CSV reader meets it: the field count, the time, then the cells left to right. A non-finite
/// cell is shown as Rust writes it (`NaN`, `inf`), the text the CSV would hold.
fn parse_row(cells: &[f64], cols: &Columns, order: &[usize], row: &mut [f64]) -> Parsed {
    if cells.len() != cols.names.len() {
        return Parsed::FieldCount(cells.len());
    }
    let non_finite = |v: f64| DataErrorKind::NonFinite {
        cell: format!("{v:?}"),
    };
    let t = cells[cols.t];
    if !t.is_finite() {
        return Parsed::BadTime(non_finite(t));
    }
    for (v, &col) in row.iter_mut().zip(order) {
        let x = cells[col];
        if !x.is_finite() {
            return Parsed::BadCell {
                t,
                col,
                kind: non_finite(x),
            };
        }
        *v = x;
    }
    Parsed::Row(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table as the CSV text it stands for (`{:?}`: shortest round-trip, `NaN`, `inf`).
    fn csv(names: &[&str], values: &[f64]) -> String {
        let mut s = names.join(",") + "\n";
        for r in values.chunks(names.len()) {
            let cells: Vec<String> = r.iter().map(|v| format!("{v:?}")).collect();
            s += &(cells.join(",") + "\n");
        }
        s
    }

    fn both(
        names: &[&str],
        values: &[f64],
    ) -> (Result<Trajectory, String>, Result<Trajectory, String>) {
        let owned: Vec<String> = names.iter().map(|s| s.to_string()).collect();
        let a = Trajectory::from_columns("x", &owned, values, Some(2)).map_err(|e| e.to_string());
        let text = csv(names, values);
        let b = Trajectory::from_reader(text.as_bytes(), "x", Some(2)).map_err(|e| e.to_string());
        (a, b)
    }

    #[test]
    fn a_table_reads_as_its_csv_text_values_and_errors_alike() {
        let names = ["tau2", "q2", "t", "tau1", "q1"];
        let good = [1.5, 0.1, 0.0, -2.0, 0.2, 1.25, 0.3, 0.01, -1.0, 1e-300];
        let (a, b) = both(&names, &good);
        assert_eq!(a.as_ref().unwrap(), b.as_ref().unwrap());
        assert_eq!(a.unwrap().tau_at(1), Some(&[-1.0, 1.25][..]));
        let cases: [(&[&str], Vec<f64>, &str); 6] = [
            (&names, vec![1.0, f64::NAN, 0.0, 0.0, 0.0], "x:2: q2: `NaN`"),
            (
                &names,
                [&good[..], &[0.0, 0.0, 0.02, 0.0, f64::INFINITY]].concat(),
                "x:4: q1: `inf`",
            ),
            (
                &names,
                [&good[..], &[0.0, 0.0, 0.01, 0.0, 0.0]].concat(),
                "x:4: t: t = 0.01 does not increase",
            ),
            (
                &["t", "q1", "q2", "tau_1", "tau2"],
                good.to_vec(),
                "x:1: tau_1: unknown column `tau_1`",
            ),
            (
                &["t", "q1", "q2", "q3"],
                vec![0.0; 4],
                "x:1: q3: extra column",
            ),
            (&["t", "q1"], vec![0.0; 2], "x:1: missing column `q2`"),
        ];
        for (names, values, want) in cases {
            let (a, b) = both(names, &values);
            let (a, b) = (a.unwrap_err(), b.unwrap_err());
            assert_eq!(a, b);
            assert!(a.starts_with(want), "{a}");
        }
        let owned = vec!["t".to_string(), "q1".to_string(), "q2".to_string()];
        let e = Trajectory::from_columns("x", &owned, &[], Some(2)).unwrap_err();
        assert!(e.to_string().contains("header but no data rows"), "{e}");
        let e = Trajectory::from_columns("x", &[], &[], Some(2)).unwrap_err();
        assert!(e.to_string().contains("the file is empty"), "{e}");
    }
}
