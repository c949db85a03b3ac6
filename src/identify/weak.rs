//! **Weak joints** ([`quantised`]): a joint whose measured torque is mostly one value — a
//! current or torque reading sitting on its resolution floor, e.g. 85 % exact zeros at a
//! 0.02 N·m step — carries too little information to identify anything. Such a joint is
//! reported as not identifiable with the reason, no effect is searched on it, and it is left
//! out of the per-joint guard and of the overall error; its rows stay in the fit (they are
//! what the data say, and the shared parameters are mostly set by the other joints).
//!
//! Rule: the most frequent torque value holds at least [`MODE_SHARE`] of a joint's samples.
//! A signal that varies by more than one quantisation step rarely repeats one value; when half
//! of the samples are the same level, the signal's typical size is below one step, and the
//! quantisation error (uniform, variance step²/12) is as large as what is left of the signal.
//! A second kind of weak joint, a torque that no model predicts (mostly noise), is found by the
//! guard from the plain fit's held-out error ([`super::guard`]).

use serde::Serialize;

use super::prepare::Prepared;
use crate::dh::{DhTable, JointKind};

/// Least share of samples on one torque value that makes a joint weak (see the module docs).
pub const MODE_SHARE: f64 = 0.5;

/// A joint that cannot be identified from the training data, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WeakJoint {
    /// 0-based joint index.
    pub joint: usize,
    /// Share of the training samples on the most frequent torque value (NaN when the joint was
    /// found weak by its held-out error instead).
    pub mode_share: f64,
    /// That value.
    pub mode_value: f64,
    /// Distinct torque values in the training data.
    pub levels: usize,
    /// Smallest step between two distinct values (the resolution, when quantised).
    pub step: f64,
    pub reason: String,
}

/// The joints of `train` whose torque sits on one value in at least [`MODE_SHARE`] of the
/// samples (files without a torque column are skipped). Memory does not grow with the log:
/// a Misra–Gries pass keeps two candidate values per joint (every value with more than a third
/// of the samples survives it), a second pass counts them exactly, and only a weak joint's
/// distinct values are collected (for the report), in a third.
pub fn quantised(train: &[Prepared], dof: usize) -> Vec<WeakJoint> {
    let each_row = |f: &mut dyn FnMut(&[f64], usize)| {
        for p in train {
            if let Some(off) = p.log.layout.tau_offset() {
                p.log.rows(p.raw_keep.0, p.raw_keep.1, |row| f(row, off));
            }
        }
    };
    // +0.0 and −0.0 are one value.
    let key = |v: f64| (v + 0.0).to_bits();
    let mut cands: Vec<[(u64, usize); 2]> = vec![[(0, 0); 2]; dof];
    let mut total = 0usize;
    each_row(&mut |row, off| {
        total += 1;
        for (j, c) in cands.iter_mut().enumerate() {
            misra_gries(c, key(row[off + j]));
        }
    });
    if total == 0 {
        return Vec::new();
    }
    let mut counts: Vec<[usize; 2]> = vec![[0; 2]; dof];
    each_row(&mut |row, off| {
        for (j, n) in counts.iter_mut().enumerate() {
            let k = key(row[off + j]);
            for (slot, c) in n.iter_mut().zip(&cands[j]) {
                if c.1 > 0 && c.0 == k {
                    *slot += 1;
                }
            }
        }
    });
    let modes: Vec<Option<(u64, usize)>> = (0..dof)
        .map(|j| {
            (0..2)
                .map(|i| (cands[j][i].0, counts[j][i]))
                .filter(|&(_, n)| n as f64 / total as f64 >= MODE_SHARE)
                .max_by_key(|&(b, n)| (n, std::cmp::Reverse(b)))
        })
        .collect();
    let mut levels: Vec<std::collections::BTreeSet<u64>> = vec![Default::default(); dof];
    if modes.iter().any(Option::is_some) {
        each_row(&mut |row, off| {
            for (j, l) in levels.iter_mut().enumerate() {
                if modes[j].is_some() {
                    l.insert(key(row[off + j]));
                }
            }
        });
    }
    let mut out = Vec::new();
    for (j, mode) in modes.iter().enumerate() {
        let Some((bits, n)) = *mode else {
            continue;
        };
        let share = n as f64 / total as f64;
        let mut values: Vec<f64> = levels[j].iter().map(|&b| f64::from_bits(b)).collect();
        values.sort_by(f64::total_cmp);
        let step = values
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(f64::INFINITY, f64::min);
        let mode = f64::from_bits(bits);
        out.push(WeakJoint {
            joint: j,
            mode_share: share,
            mode_value: mode,
            levels: values.len(),
            step,
            reason: format!(
                "joint {}: {:.0} % of its training torque samples are exactly {mode} ({} distinct values, smallest step {}): the reading sits on its resolution floor, so its torque carries too little information to identify this joint — it is fitted with the others but not reported as identified, and left out of the overall error",
                j + 1,
                100.0 * share,
                values.len(),
                if step.is_finite() { format!("{step:.3e}") } else { "none".into() },
            ),
        });
    }
    out
}

/// One Misra–Gries step with two counters: afterwards every value seen more than a third of
/// the time so far is among the candidates (a zero count is an empty slot).
fn misra_gries(c: &mut [(u64, usize); 2], k: u64) {
    if let Some(slot) = c.iter_mut().find(|s| s.1 > 0 && s.0 == k) {
        slot.1 += 1;
    } else if let Some(slot) = c.iter_mut().find(|s| s.1 == 0) {
        *slot = (k, 1);
    } else {
        for s in c.iter_mut() {
            s.1 -= 1;
        }
    }
}

/// The joints an overall error pools: the identifiable (not `weak`) joints of the unit most
/// joints share (revolute, N·m, on a tie); `None` when that is every joint. Relative errors of
/// different units are not added: a prismatic torso's 185 N gravity load would swamp the arm's
/// N·m.
pub fn pooled_joints(
    table: Option<&DhTable>,
    dof: usize,
    weak: &[WeakJoint],
) -> Option<Vec<usize>> {
    let (r, p) = live_by_unit(table, dof, weak);
    let kept = if p.len() > r.len() { p } else { r };
    (kept.len() < dof && !kept.is_empty()).then_some(kept)
}

/// The identifiable (not `weak`) joints grouped by unit (revolute, prismatic), empty groups
/// left out; every joint in one group when all are weak.
pub fn unit_groups(table: Option<&DhTable>, dof: usize, weak: &[WeakJoint]) -> Vec<Vec<usize>> {
    let (r, p) = live_by_unit(table, dof, weak);
    if r.is_empty() && p.is_empty() {
        return vec![(0..dof).collect()];
    }
    [r, p].into_iter().filter(|g| !g.is_empty()).collect()
}

/// The identifiable (not `weak`) joints: the revolute ones and the prismatic ones.
fn live_by_unit(
    table: Option<&DhTable>,
    dof: usize,
    weak: &[WeakJoint],
) -> (Vec<usize>, Vec<usize>) {
    let prismatic = |j: usize| {
        table
            .and_then(|t| t.joints.get(j))
            .is_some_and(|jt| jt.kind == JointKind::Prismatic)
    };
    (0..dof)
        .filter(|&j| !weak.iter().any(|w| w.joint == j))
        .partition(|&j| !prismatic(j))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identify::synth::{generate, Spec};
    use crate::identify::Config;
    use crate::log::Log;

    #[test]
    fn a_torque_mostly_of_quantised_zeros_is_weak_and_a_live_one_is_not() {
        let arm = crate::arms::resolve("planar2").unwrap();
        let mut spec = Spec::new(arm.dh_table().unwrap(), 3);
        spec.duration = 10.0;
        let mut traj = generate(&spec);
        // Joint 2's torque scaled to an RMS of 0.4 of a 0.02 step, then quantised: a reading on
        // its resolution floor (exact zeros while |τ| < 1.25 RMS, most of the time, and a few
        // levels at the peaks); joint 1 left as simulated.
        let tau = traj.tau.as_mut().unwrap();
        let rms = (tau.iter().skip(1).step_by(2).map(|v| v * v).sum::<f64>()
            / (tau.len() / 2) as f64)
            .sqrt();
        let step = 0.02;
        for v in tau.iter_mut().skip(1).step_by(2) {
            *v = (*v / rms * 0.4).round() * step;
        }
        let prep = Prepared::new(Log::from(traj), &Config::default()).unwrap();
        let weak = quantised(std::slice::from_ref(&prep), 2);
        assert_eq!(weak.len(), 1, "{weak:?}");
        let w = &weak[0];
        assert_eq!((w.joint, w.mode_value), (1, 0.0));
        // A smooth signal spends well over half its time within 1.25 RMS of zero (a sinusoid
        // 68 %, a Gaussian 79 %), and crosses it at its peaks.
        assert!(
            w.mode_share > MODE_SHARE && w.mode_share < 1.0,
            "{}",
            w.mode_share
        );
        assert!(w.levels >= 3, "{}", w.levels);
        assert!((w.step - step).abs() < 1e-12, "{}", w.step);
        assert!(w.reason.contains("joint 2"), "{}", w.reason);
    }

    #[test]
    fn misra_gries_keeps_every_value_over_a_third_of_the_stream() {
        // Oracle: exact counts. Streams of a few values with skewed, random frequencies, in
        // random order; every value seen more than n/3 times must be a candidate at the end.
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for _ in 0..500 {
            let n = rng.gen_range(1..400);
            let skew: f64 = rng.gen_range(0.0..1.0);
            let stream: Vec<u64> = (0..n)
                .map(|_| {
                    if rng.gen_bool(skew) {
                        0
                    } else {
                        rng.gen_range(0..6)
                    }
                })
                .collect();
            let mut c = [(0u64, 0usize); 2];
            for &k in &stream {
                misra_gries(&mut c, k);
            }
            for v in 0..6u64 {
                let count = stream.iter().filter(|&&k| k == v).count();
                if 3 * count > n {
                    assert!(
                        c.iter().any(|s| s.1 > 0 && s.0 == v),
                        "{v} seen {count} of {n}: {c:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_overall_error_pools_one_unit_and_no_weak_joint() {
        // SCARA: joints 1, 2, 4 revolute (N·m), joint 3 prismatic (N).
        let table = crate::arms::resolve("scara").unwrap().dh_table().unwrap();
        let weak = |j| WeakJoint {
            joint: j,
            mode_share: 0.9,
            mode_value: 0.0,
            levels: 3,
            step: 0.1,
            reason: String::new(),
        };
        assert_eq!(pooled_joints(Some(&table), 4, &[]), Some(vec![0, 1, 3]));
        assert_eq!(pooled_joints(Some(&table), 4, &[weak(3)]), Some(vec![0, 1]));
        let planar = crate::arms::resolve("planar2").unwrap().dh_table().unwrap();
        assert_eq!(pooled_joints(Some(&planar), 2, &[]), None);
        assert_eq!(pooled_joints(Some(&planar), 2, &[weak(0)]), Some(vec![1]));
        assert_eq!(
            unit_groups(Some(&table), 4, &[weak(1)]),
            vec![vec![0, 3], vec![2]]
        );
        assert_eq!(unit_groups(Some(&planar), 2, &[]), vec![vec![0, 1]]);
    }
}
