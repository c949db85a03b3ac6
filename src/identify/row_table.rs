//! What the passes over one file's rows can share: its rows evaluated once for a layout
//! ([`RowTable`]) and, across the folds of a study, its states, torque and base regressor
//! ([`GridBaseCache`]). Built by [`super::rows`].

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use super::layout::Layout;
use crate::derivative::States;

/// A file's unfiltered regression rows (and measured torque) on its whole grid, per joint its active columns
/// (`rows[j][k · a_j + l]` for joint `j`'s `l`-th active column at grid sample `k`): evaluated
/// once per cut-off and read by every pass the cut-off scan makes over them (the fits with both
/// regression filters and their predictions), where each pass evaluated the regressor anew.
#[derive(Debug)]
pub(super) struct RowTable {
    /// The layout the rows are of (a pass with another reads nothing from the table).
    pub(super) layout: Layout,
    pub(super) widths: Vec<usize>,
    pub(super) rows: Vec<Vec<f64>>,
    /// The measured torque on the grid, per joint.
    pub(super) tau: Vec<Vec<f64>>,
}

/// Largest [`RowTable`]s the cut-off scan keeps (bytes, all files of one cut-off): beyond it the
/// passes evaluate the rows themselves (memory stays bounded whatever the arm).
pub(super) const ROW_TABLE_BYTES: usize = 48 << 20;

impl RowTable {
    /// Whether the table holds the rows of `layout` (see [`Layout::same_rows`]).
    pub(super) fn fits(&self, layout: &Layout) -> bool {
        self.layout.same_rows(layout)
    }

    /// Joint `j`'s measured torque on grid samples `lo..hi`.
    pub(super) fn tau(&self, j: usize, lo: usize, hi: usize) -> &[f64] {
        &self.tau[j][lo..hi]
    }

    /// Joint `j`'s active columns at grid sample `k`.
    pub(super) fn row(&self, j: usize, k: usize) -> &[f64] {
        let w = self.widths[j];
        &self.rows[j][k * w..(k + 1) * w]
    }
}

/// What one file's rows at one cut-off are made of besides the effect columns — its estimated
/// states, measured torque and base regressor on the whole grid, window by window as
/// [`RowTable::new`] evaluates them: the same in every fold of a leave-one-out study and in a
/// rescan (only the effect columns depend on the training set, through their friction scales),
/// so made once ([`GridBaseCache`]).
pub(super) struct GridBase {
    /// Per window `(a, b)` of [`cores`](super::prepare::cores): its states, torque and base regressor.
    pub(super) parts: Vec<((usize, usize), BasePart)>,
}

pub(super) struct BasePart {
    pub(super) st: States,
    pub(super) tau: Vec<Vec<f64>>,
    /// `[(k - a) * dof * nb ..]`: [`BaseModel::eval`](super::base::BaseModel::eval) of grid sample `k`.
    pub(super) yb: Vec<f64>,
}

/// Largest total of [`GridBase`]s a [`GridBaseCache`] keeps (bytes); past it, rows are
/// evaluated as without it.
pub(super) const GRID_BASE_BYTES: usize = 64 << 20;

/// [`GridBase`]s by (file, cut-off), shared by its clones (the folds of a study run in
/// parallel), up to [`GRID_BASE_BYTES`] in all. The default holds none (a single
/// identification scans each file at each cut-off once: nothing to share, memory to lose);
/// [`GridBaseCache::shared`] is a study's.
#[derive(Clone, Default)]
pub struct GridBaseCache(pub(super) Option<Arc<Mutex<GridBases>>>);

#[derive(Default)]
pub(super) struct GridBases {
    pub(super) bytes: usize,
    pub(super) map: HashMap<((usize, usize), usize, u64), Arc<GridBase>>,
}

impl std::fmt::Debug for GridBaseCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let held = self
            .0
            .as_ref()
            .and_then(|c| c.lock().ok().map(|g| g.map.len()))
            .unwrap_or(0);
        write!(f, "GridBaseCache({held} held)")
    }
}

impl GridBaseCache {
    /// A cache that holds what it makes (for the folds of a study).
    pub(super) fn shared() -> Self {
        GridBaseCache(Some(Arc::default()))
    }
}
