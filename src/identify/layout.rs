//! The column layout of a regression: base parameters (per joint only those that can be non-zero in
//! its rows), then effect terms. Chosen for the training data by [`super::columns`].

use super::ls::Accumulator;
use crate::effects::{Run, Scales, Term};

/// Which columns the regression has: base parameters, then effect terms.
#[derive(Debug, Clone)]
pub struct Layout {
    pub dof: usize,
    pub nb: usize,
    pub base_names: Vec<String>,
    pub base_exprs: Vec<String>,
    pub terms: Vec<Term>,
    pub scales: Vec<Scales>,
    /// Per joint, the base columns that can be non-zero in its rows (structurally zero ones
    /// are left out of its accumulators).
    pub base_active: Vec<Vec<usize>>,
    /// Base columns the training data cannot determine (combinations of the other columns):
    /// held at zero, never fitted ([`super::run_prepared`]); the report names them.
    pub fixed: Vec<usize>,
    /// Coefficients (one per column, zero on the [`Effect::LOADED`](crate::effects::Effect::LOADED) ones) of the first-stage
    /// model whose predicted torque the load-dependent columns use; empty when there are none.
    pub load: Vec<f64>,
    /// The training runs ([`crate::log::Log::run`]), in order, each once: a per-run term's
    /// [`Term::run`] indexes them.
    pub runs: Vec<String>,
    /// Per joint, the share of training samples at rest (1 − mean |tanh(q̇ / v)|); `asym_coulomb`
    /// is searched only where it reaches [`crate::effects::Effect::ASYM_REST_MIN`].
    pub at_rest: Vec<f64>,
}

impl Layout {
    /// Regressor columns (without the target).
    pub fn ncols(&self) -> usize {
        self.nb + self.terms.len()
    }

    /// Whether `other` gives every state the same rows (the same columns, friction scales and
    /// first-stage model): a [`super::rows::RowTable`] of one serves the other.
    pub(super) fn same_rows(&self, other: &Layout) -> bool {
        self.dof == other.dof
            && self.nb == other.nb
            && self.terms == other.terms
            && self.scales == other.scales
            && self.base_active == other.base_active
            && self.load == other.load
            && self.runs == other.runs
    }

    /// Which run the rows of a log of recording `run` are in.
    pub fn run_of(&self, run: &str) -> Run {
        match self.runs.iter().position(|r| r == run) {
            Some(i) => Run::Training(i),
            None => Run::Unseen {
                runs: self.runs.len(),
            },
        }
    }

    /// This layout with `terms` added (sorted, each once) and the first-stage model of the
    /// load-dependent columns ([`Layout::load`]) moved with the column indices: new terms sort
    /// before the load-dependent ones and shift them.
    pub(super) fn with_terms<'a>(&self, terms: impl IntoIterator<Item = &'a Term>) -> Layout {
        let mut l2 = self.clone();
        l2.terms.extend(terms);
        l2.terms.sort();
        l2.terms.dedup();
        if !l2.load.is_empty() {
            let mut load = vec![0.0; l2.ncols()];
            for (c, &v) in self.load.iter().enumerate() {
                let at = if c < l2.nb {
                    Some(c)
                } else {
                    l2.col(&self.terms[c - l2.nb])
                };
                if let Some(at) = at {
                    load[at] = v;
                }
            }
            l2.load = load;
        }
        l2
    }

    /// Column index of a term.
    pub fn col(&self, t: &Term) -> Option<usize> {
        self.terms.iter().position(|x| x == t).map(|i| self.nb + i)
    }

    /// Columns that can be non-zero in joint `j`'s rows: its base columns and its own terms.
    pub fn active(&self, j: usize) -> Vec<usize> {
        let mut a = self.base_active[j].clone();
        a.extend(
            (0..self.terms.len())
                .filter(|&i| self.terms[i].joint == j)
                .map(|i| self.nb + i),
        );
        a
    }

    /// Empty `[joint]` accumulators for rows of this layout (with the target column).
    pub(super) fn accumulators(&self) -> Vec<Accumulator> {
        (0..self.dof)
            .map(|j| Accumulator::with_active(self.ncols() + 1, self.active(j)))
            .collect()
    }

    /// Name of a column.
    pub fn col_name(&self, c: usize) -> String {
        if c < self.nb {
            self.base_names[c].clone()
        } else {
            self.terms[c - self.nb].label()
        }
    }
}
