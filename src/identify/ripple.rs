//! Stage 6a, **position ripple** ([`Effect::RIPPLE`]): torque that repeats with the joint's
//! position, `a·sin(k·q) + b·cos(k·q)` (cogging, gear and sensor ripple). The columns are linear
//! in `a`, `b` but not in the wavenumber `k`, so `k` comes first, per joint, from the residual of
//! the model selected without them: the peak of its periodogram against `qⱼ`
//! ([`periodogram_peak`], least squares of the residual on `sin kq`, `cos kq` over a grid of `k`
//! a quarter period apart across the joint's range, refined around the best). Two gates follow,
//! because a residual that is smooth in time can hold a peak that predicts held-out blocks without
//! being a ripple: the peak must stand out of its neighbouring wavenumbers by more than noise
//! would anywhere in the scan ([`Peak::significant`]), and with that `k` the pair is searched on
//! top of the model like any other effect (the same held-out test over time blocks,
//! [`super::select()`]). On a model without ripple no pair is added.
//!
//! A ripple whose period is about the joint's range is partly a constant and a line there, which
//! the joint's offset and spring take when the first stage adds them, and the periodogram of what
//! they leave peaks off the ripple (suite case: k 6.3 for 4.4, the spring then extrapolated to
//! 31× the oracle's validation error). So the joint is scanned on the residual of the model
//! without them (beyond a line where the model holds a spring), `k` is refined by backfitting
//! (with the pair in the model, the joint's partial residual is scanned again) and then fitted
//! by least squares like the model's other parameters, and once the pair is
//! in, each stand-in must pass the selection test again or it goes.

use serde::Serialize;

use super::base::BaseModel;
use super::layout::Layout;
use super::prepare::{cores, Prepared};
use super::problem::{with_hint, Problem};
use super::rows::Rows;
use super::select::{
    accept, add_collinear, chain_stages, joint_group, passes_again, select, select_units, Rules,
    Selected, Selection,
};
use super::{Config, IdentifyError};
use crate::effects::{Effect, EffectsSpec, Term};

/// Smallest wavenumber searched (rad⁻¹): slower shapes are a spring, an offset or an error of
/// the gravity model, not a ripple.
pub const K_MIN: f64 = 2.0;
/// Largest wavenumber searched (rad⁻¹).
pub const K_MAX: f64 = 60.0;
/// Residual samples per joint the periodogram reads at most (evenly strided).
const MAX_SAMPLES: usize = 100_000;

/// One joint's wavenumber scan, as the report shows it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RippleScan {
    /// 0-based.
    pub joint: usize,
    /// The periodogram's peak (rad⁻¹ or m⁻¹), the wavenumber of the joint's ripple columns.
    pub k: f64,
    /// Share of the residual's variance a sine at `k` explains (in sample).
    pub share: f64,
    /// The peak's power over its neighbours' median ([`Peak::prominence`]).
    pub prominence: f64,
    /// Whether it stands out of noise ([`Peak::significant`]); with `--effects auto` only such
    /// a joint's pair is searched.
    pub significant: bool,
    /// Whether the pair (or one of it) passed the selection test.
    pub accepted: bool,
}

/// A periodogram's highest peak ([`periodogram_peak`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Peak {
    /// Its wavenumber.
    pub k: f64,
    /// Share of the residual's within-run variance the sine pair at `k` explains.
    pub share: f64,
    /// Its power over the median power of the grid wavenumbers around it (the background).
    pub prominence: f64,
    /// Independent wavenumbers the scan compared (range × span / 2π): the multiple comparisons
    /// the significance threshold pays for.
    pub tested: f64,
}

impl Peak {
    /// Whether the peak stands out of its background enough to be tested as a ripple. A sine
    /// pair's power on noise is χ²₂-distributed (exponential), so one power exceeds `t` medians
    /// with probability `2⁻ᵗ` and the largest of `m` independent ones about `m·2⁻ᵗ`; the
    /// threshold is `t = log₂(m / 0.01)`. The scan's maximum over a continuous `k`, against the
    /// median of a few neighbours, exceeds it more often: in about 10 % of white-noise draws
    /// (400 draws of 2k–16k samples; 1.44 t would pass 1 %). That is a pre-filter, not the test:
    /// the held-out test over time blocks follows. Stricter (1.5 t) cost three true ripples of
    /// the suite and removed no false positive.
    pub fn significant(&self) -> bool {
        self.prominence >= (self.tested.max(1.0) / 0.01).log2()
    }
}

/// Fewest grid powers a background median is taken from (four per independent wavenumber).
const MIN_BACKGROUND: usize = 16;

/// Half-width of the background window around a peak, in independent wavenumbers (`2π/range`).
const BACKGROUND_HALF_WIDTH: f64 = 8.0;

/// The wavenumber in `[k_lo, k_hi]` whose sine and cosine of `q` explain most of `r` by least
/// squares, everything centred within each `run` (a constant per run — a sensor re-zeroed between
/// runs — is not a ripple), with the share of `r`'s within-run variance they explain and how far
/// it stands out of its neighbours ([`Peak`]); `None` when `q` spans less than one period of
/// `k_hi` or `r` is constant within runs. With `line` (the joint's model holds a spring) the pair's
/// power is measured beyond a line in `q` too: `r` and the pair taken orthogonal to `q` centred
/// within each run.
pub fn periodogram_peak(
    (q, r, run): (&[f64], &[f64], &[usize]),
    (k_lo, k_hi): (f64, f64),
    line: bool,
) -> Option<Peak> {
    let n = q.len().min(r.len()).min(run.len());
    if n < 8 {
        return None;
    }
    let range = span(&q[..n]);
    let k_lo = k_lo.max(std::f64::consts::TAU / range);
    if !(range.is_finite() && k_lo < k_hi) {
        return None;
    }
    let runs = run[..n].iter().max().map_or(0, |m| m + 1);
    let (mut sum, mut count) = (vec![0.0; runs], vec![0usize; runs]);
    for (&v, &g) in r[..n].iter().zip(run) {
        sum[g] += v;
        count[g] += 1;
    }
    let rc: Vec<f64> = r[..n]
        .iter()
        .zip(run)
        .map(|(v, &g)| v - sum[g] / count[g] as f64)
        .collect();
    let mut total: f64 = rc.iter().map(|v| v * v).sum();
    // With `line`, q centred within each run: the line the pair's power is measured beyond.
    let u: Option<Vec<f64>> = line.then(|| {
        let mut qs = vec![0.0; runs];
        for (&x, &g) in q[..n].iter().zip(run) {
            qs[g] += x;
        }
        q[..n]
            .iter()
            .zip(run)
            .map(|(&x, &g)| x - qs[g] / count[g] as f64)
            .collect()
    });
    if let Some(u) = &u {
        let uu: f64 = u.iter().map(|v| v * v).sum();
        let ru: f64 = u.iter().zip(&rc).map(|(a, b)| a * b).sum();
        if uu > 0.0 {
            total -= ru * ru / uu;
        }
    }
    if total <= 0.0 {
        return None;
    }
    let power = |k: f64| explained(&q[..n], &rc, &run[..n], &count, u.as_deref(), k);
    // A grid step that moves the phase by at most a quarter period across the range.
    let step = std::f64::consts::FRAC_PI_2 / range;
    let steps = ((k_hi - k_lo) / step).ceil() as usize + 1;
    use rayon::prelude::*;
    let grid: Vec<(f64, f64)> = (0..steps)
        .into_par_iter()
        .map(|i| {
            let k = (k_lo + i as f64 * step).min(k_hi);
            (k, power(k))
        })
        .collect();
    let (mut k, mut p) =
        grid.iter().copied().fold(
            (k_lo, f64::NEG_INFINITY),
            |b, g| if g.1 > b.1 { g } else { b },
        );
    // Refine within a step either side (the true peak is that close to a grid point).
    let fine: Vec<(f64, f64)> = (-16..=16)
        .into_par_iter()
        .map(|i| {
            let kk = (k + i as f64 * step / 16.0).clamp(k_lo, k_hi);
            (kk, power(kk))
        })
        .collect();
    for (kk, pp) in fine {
        if pp > p {
            (k, p) = (kk, pp);
        }
    }
    // The background: grid powers within a few independent wavenumbers either side, without the
    // peak's own lobe (1.5 independent wavenumbers either side); the whole scan outside the lobe
    // when that window holds too few. Too few even then (a joint that spans only a few periods of
    // the shortest ripple): no background to stand out of, so no prominence.
    let independent = std::f64::consts::TAU / range;
    let outside = |limit: f64| -> Vec<f64> {
        let mut v: Vec<f64> = grid
            .iter()
            .filter(|(kk, _)| {
                let d = (kk - k).abs();
                d > 1.5 * independent && d <= limit
            })
            .map(|g| g.1)
            .collect();
        v.sort_by(f64::total_cmp);
        v
    };
    let mut around = outside(BACKGROUND_HALF_WIDTH * independent);
    if around.len() < MIN_BACKGROUND {
        around = outside(f64::INFINITY);
    }
    let median = around.get(around.len() / 2).copied().unwrap_or(0.0);
    let prominence = if around.len() >= MIN_BACKGROUND / 2 && median > 0.0 {
        p / median
    } else {
        0.0
    };
    Some(Peak {
        k,
        share: p / total,
        prominence,
        tested: (k_hi - k_lo) / independent,
    })
}

/// Greatest minus least of `q` (−∞ when empty).
fn span(q: &[f64]) -> f64 {
    let (lo, hi) = q
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    hi - lo
}

/// Sum of squares of `r` (centred within each run) that `sin(kq)`, `cos(kq)`, centred within
/// each run (`count` samples each), explain by least squares — beyond the line `u` (q centred
/// within each run) when given: both `r` and the pair are then taken orthogonal to it.
fn explained(
    q: &[f64],
    r: &[f64],
    run: &[usize],
    count: &[usize],
    u: Option<&[f64]>,
    k: f64,
) -> f64 {
    let mut s = vec![0.0; count.len()];
    let mut c = vec![0.0; count.len()];
    let (mut ss, mut cc, mut sc, mut rs, mut rcos) = (0.0, 0.0, 0.0, 0.0, 0.0);
    // Products with the line (zero without one).
    let (mut uu, mut us, mut uc, mut ur) = (0.0, 0.0, 0.0, 0.0);
    for (i, ((&x, &y), &g)) in q.iter().zip(r).zip(run).enumerate() {
        let (si, co) = (k * x).sin_cos();
        s[g] += si;
        c[g] += co;
        ss += si * si;
        cc += co * co;
        sc += si * co;
        rs += y * si;
        rcos += y * co;
        if let Some(u) = u {
            let ui = u[i];
            uu += ui * ui;
            us += ui * si;
            uc += ui * co;
            ur += ui * y;
        }
    }
    // Centred sums (r is centred already, so Σr·(sin − run mean) = Σr·sin).
    for ((s, c), &m) in s.iter().zip(&c).zip(count) {
        let m = m.max(1) as f64;
        ss -= s * s / m;
        cc -= c * c / m;
        sc -= s * c / m;
    }
    // Beyond the line (Frisch–Waugh): every sum less its part along `u` (centred, so
    // Σu·(sin − run mean) = Σu·sin).
    if uu > 0.0 {
        ss -= us * us / uu;
        cc -= uc * uc / uu;
        sc -= us * uc / uu;
        rs -= ur * us / uu;
        rcos -= ur * uc / uu;
    }
    let det = ss * cc - sc * sc;
    if det <= 1e-12 * (ss * cc).max(f64::MIN_POSITIVE) {
        // sin and cos indistinguishable on these samples: one column.
        return if ss > 0.0 { rs * rs / ss } else { 0.0 };
    }
    let a = (cc * rs - sc * rcos) / det;
    let b = (ss * rcos - sc * rs) / det;
    a * rs + b * rcos
}

/// One joint's positions and residuals at the same samples, and each sample's file.
type Samples = (Vec<f64>, Vec<f64>, Vec<usize>);

/// Per joint in `joints`, the positions and residuals `τ − τ̂` of `terms`' fit on `problem` at
/// evenly strided grid samples of the training files (the model predicted from the states),
/// `τ̂` without the fitted torque of the terms in `leave_out` (a partial residual).
fn residuals(
    base: &BaseModel,
    problem: &Problem,
    train: &[Prepared],
    (terms, leave_out): (&[Term], &[Term]),
    joints: &[usize],
) -> Result<Vec<Samples>, crate::identify::RankError> {
    let layout = &problem.layout;
    let subset = problem.subset(terms);
    let w = problem.weights(&subset)?;
    let fit = problem.fit(&subset, &w)?;
    let nc = layout.ncols();
    let mut x = vec![0.0; nc];
    for (&c, &v) in subset.iter().zip(&fit.x) {
        x[c] = v;
    }
    for c in leave_out.iter().filter_map(|t| layout.col(t)) {
        x[c] = 0.0;
    }
    let total: usize = train.iter().map(|p| p.keep.1 - p.keep.0).sum();
    let stride = total.div_ceil(MAX_SAMPLES).max(1);
    let mut out = vec![(Vec::new(), Vec::new(), Vec::new()); joints.len()];
    for (file, p) in train.iter().enumerate() {
        let mut rows = Rows::for_log(base, layout, &p.log);
        for (a, b) in cores(p, p.keep.0, p.keep.1) {
            let first = a.div_ceil(stride) * stride;
            if first >= b {
                continue;
            }
            let st = p.states(a, b);
            let tau = p.grid_tau(a, b);
            for k in (first..b).step_by(stride) {
                let row = rows.fill_grid(&st, k);
                for (o, &j) in out.iter_mut().zip(joints) {
                    let pred: f64 = row[j * nc..(j + 1) * nc]
                        .iter()
                        .zip(&x)
                        .map(|(a, b)| a * b)
                        .sum();
                    o.0.push(st.q[j][k - st.lo]);
                    o.1.push(tau[j][k - a] - pred);
                    o.2.push(file);
                }
            }
        }
    }
    Ok(out)
}

/// The ripple stage (see the module docs): with `--effects auto` every joint not in `skip` is
/// scanned and its pair searched; with a fixed list, the joints whose ripple it names are
/// scanned and the pair added. Without any accepted or declared, `selected` is returned as it
/// is (with the scans, for the report).
pub(super) fn ripple_stage(
    base: &BaseModel,
    train: &[Prepared],
    cfg: &Config,
    selected: Selected,
    (skip, searched): (&[usize], &[Term]),
) -> Result<(Selected, Vec<RippleScan>), IdentifyError> {
    let n = base.dof();
    let fixed: Vec<Term> = match &cfg.effects {
        EffectsSpec::Auto => Vec::new(),
        EffectsSpec::Fixed(t) => t.iter().copied().filter(|t| t.effect.is_ripple()).collect(),
    };
    let joints: Vec<usize> = match &cfg.effects {
        EffectsSpec::Auto => (0..n).filter(|j| !skip.contains(j)).collect(),
        EffectsSpec::Fixed(_) => {
            let mut j: Vec<usize> = fixed.iter().map(|t| t.joint).collect();
            j.sort();
            j.dedup();
            j
        }
    };
    if joints.is_empty() {
        return Ok((selected, Vec::new()));
    }
    let springs: Vec<usize> = selected
        .selection
        .terms
        .iter()
        .filter(|t| t.effect == Effect::Spring)
        .map(|t| t.joint)
        .collect();
    let fail = |e| IdentifyError::Rank(with_hint(e, train));
    let samples = scan_residuals(base, train, &selected, &joints).map_err(fail)?;
    let mut scans = scan_joints(&joints, &samples, &fixed, &springs)?;
    refine(base, train, cfg, &selected, &mut scans, &springs).map_err(fail)?;
    let spans: Vec<(usize, f64)> = joints
        .iter()
        .zip(&samples)
        .map(|(&j, (q, _, _))| (j, span(q)))
        .collect();
    least_squares_k(base, train, cfg, &selected, (&mut scans, &spans)).map_err(fail)?;
    let found = |t: &Term| scans.iter().any(|s| s.joint == t.joint);
    // Each joint's sine and cosine are one candidate: the ripple's phase is unknown.
    let search: Vec<Vec<Term>> = match &cfg.effects {
        EffectsSpec::Auto => scans
            .iter()
            .filter(|s| s.significant)
            .map(|s| {
                Effect::RIPPLE
                    .map(|effect| Term::new(effect, s.joint))
                    .to_vec()
            })
            .collect(),
        EffectsSpec::Fixed(_) => Vec::new(),
    };
    let fixed: Vec<Term> = fixed.into_iter().filter(found).collect();
    if search.is_empty() && fixed.is_empty() {
        return Ok((selected, scans));
    }
    let Selected {
        problem,
        selection: first,
        declared,
    } = selected;
    let l2 = with_ripple(
        &problem.layout,
        &scans,
        fixed.iter().chain(search.iter().flatten()),
    );
    let p2 = Problem::build(base, l2, train, cfg.blocks);
    let start: Vec<Term> = first.terms.iter().chain(&fixed).copied().collect();
    let mut second = select_units(&p2, &start, &search, &cfg.rules)?;
    with_joint_groups(&p2, &mut second, &search, searched, &cfg.rules)?;
    if fixed.is_empty() && second.steps.is_empty() {
        let mut first = first;
        add_collinear(&mut first.collinear, second.collinear);
        return Ok((
            Selected {
                problem,
                selection: first,
                declared,
            },
            scans,
        ));
    }
    if !second.steps.is_empty() {
        // A ripple hides smaller effects in its residual (a per-run offset on the same joint
        // most of all): with it in the model, the first stage's candidates are searched again.
        let again = select(&p2, &second.terms, searched, &cfg.rules)?;
        second.steps.extend(again.steps);
        add_collinear(&mut second.collinear, again.collinear);
        second.terms = again.terms;
        second.stopped_on = again.stopped_on;
    }
    for s in &mut scans {
        s.accepted = second
            .terms
            .iter()
            .any(|t| t.effect.is_ripple() && t.joint == s.joint);
    }
    let dropped = drop_stand_ins(&p2, &first, &mut second, &cfg.rules)?;
    second.stopped_on = second.stopped_on.or(first.stopped_on.clone());
    Ok((
        chain_stages(p2, first, second, declared, fixed, &dropped),
        scans,
    ))
}

/// Per joint in `joints`, the residual its scan reads: that of the model without the joint's
/// offset and spring ([`stand_in`]; they go back to the selection test with the ripple in the
/// model), the model as it is for a joint without them.
fn scan_residuals(
    base: &BaseModel,
    train: &[Prepared],
    selected: &Selected,
    joints: &[usize],
) -> Result<Vec<Samples>, crate::identify::RankError> {
    let terms = &selected.selection.terms;
    let (own, shared): (Vec<usize>, Vec<usize>) = joints
        .iter()
        .partition(|&&j| terms.iter().any(|t| stand_in(t, j)));
    let mut by_joint: Vec<(usize, Samples)> = shared
        .iter()
        .copied()
        .zip(residuals(
            base,
            &selected.problem,
            train,
            (terms, &[]),
            &shared,
        )?)
        .collect();
    for j in own {
        let without: Vec<Term> = terms.iter().copied().filter(|t| !stand_in(t, j)).collect();
        let s = residuals(base, &selected.problem, train, (&without, &[]), &[j])?;
        by_joint.extend(s.into_iter().map(|s| (j, s)));
    }
    by_joint.sort_by_key(|(j, _)| *j);
    Ok(by_joint.into_iter().map(|(_, s)| s).collect())
}

/// The first stage's offsets and springs on a joint whose ripple is now in `second`'s model stood
/// in for part of it: each must pass the selection test again against the model without it, or
/// it leaves `second` (as in the load stage). Returns those that left.
fn drop_stand_ins(
    p2: &Problem,
    first: &Selection,
    second: &mut Selection,
    rules: &Rules,
) -> Result<Vec<Term>, IdentifyError> {
    let mut dropped = Vec::new();
    for s in first.steps.iter().rev() {
        let j = s.added.joint;
        let rippled = |t: &Term| t.effect.is_ripple() && t.joint == j;
        if !stand_in(&s.added, j) || !second.terms.iter().any(rippled) {
            continue;
        }
        if !passes_again(p2, &mut second.terms, s.added, rules)? {
            dropped.push(s.added);
        }
    }
    Ok(dropped)
}

/// A joint's offset and spring: a ripple over a short range is partly a constant and a line,
/// which these take when they enter the model before it.
fn stand_in(t: &Term, j: usize) -> bool {
    t.joint == j && matches!(t.effect, Effect::Spring | Effect::Offset)
}

/// The significant scans' indices and their joints' ripple pairs.
fn significant_pairs(scans: &[RippleScan]) -> (Vec<usize>, Vec<Term>) {
    let live: Vec<usize> = (0..scans.len()).filter(|&i| scans[i].significant).collect();
    let pairs = live
        .iter()
        .flat_map(|&i| Effect::RIPPLE.map(|e| Term::new(e, scans[i].joint)))
        .collect();
    (live, pairs)
}

/// Scans of the pair's wavenumber by backfitting (at most this many per joint): the rigid-body
/// columns take part of a ripple that is not in the model, which moves the first scan's peak.
const REFINE_ROUNDS: usize = 2;

/// Backfitting of each significant scan's wavenumber: with the pair at `k` in the model, the
/// joint's partial residual (the residual plus the fitted torque of the pair and of the joint's
/// offset and spring) is scanned again, and `k` moves to its peak while that stays significant.
fn refine(
    base: &BaseModel,
    train: &[Prepared],
    cfg: &Config,
    selected: &Selected,
    scans: &mut [RippleScan],
    springs: &[usize],
) -> Result<(), crate::identify::RankError> {
    for _ in 0..REFINE_ROUNDS {
        let (live, pairs) = significant_pairs(scans);
        if live.is_empty() {
            return Ok(());
        }
        let layout = with_ripple(&selected.problem.layout, scans, pairs.iter());
        let p = Problem::build(base, layout, train, cfg.blocks);
        let mut terms = selected.selection.terms.clone();
        terms.extend(&pairs);
        let mut moved = false;
        for &i in &live {
            let j = scans[i].joint;
            let out: Vec<Term> = terms
                .iter()
                .copied()
                .filter(|t| t.joint == j && (t.effect.is_ripple() || stand_in(t, j)))
                .collect();
            let s = residuals(base, &p, train, (&terms, &out), &[j])?;
            let (q, r, run) = &s[0];
            let line = springs.contains(&j);
            let Some(peak) = periodogram_peak((q, r, run), (K_MIN, K_MAX), line) else {
                continue;
            };
            if !peak.significant() {
                continue;
            }
            let sc = &mut scans[i];
            moved |= (peak.k - sc.k).abs() > 1e-3 * sc.k;
            (sc.k, sc.share, sc.prominence) = (peak.k, peak.share, peak.prominence);
        }
        if !moved {
            return Ok(());
        }
    }
    Ok(())
}

/// Golden-section steps of [`least_squares_k`]: the bracket shrinks to 0.618¹⁰ (under 1 %) of its
/// width.
const GOLDEN_STEPS: usize = 10;

/// The least-squares wavenumber: each significant scan's `k` moves to the minimum over `k` of the
/// weighted residual sum of squares of the model with every scanned pair, within half an
/// independent wavenumber (`π / span` of the joint's positions) either side (golden-section
/// search, the other joints' `k` held), if that is lower than at the periodogram's `k`. The
/// periodogram reads a partial residual that the model's other columns still shade; `k` is a
/// parameter of the model like its coefficients, so it is fitted like them.
fn least_squares_k(
    base: &BaseModel,
    train: &[Prepared],
    cfg: &Config,
    selected: &Selected,
    (scans, spans): (&mut [RippleScan], &[(usize, f64)]),
) -> Result<(), crate::identify::RankError> {
    let (live, pairs) = significant_pairs(scans);
    if live.is_empty() {
        return Ok(());
    }
    // With a constant per run on each joint scanned, as the periodogram has: otherwise the
    // wavenumber bends to fit the per-run offsets the model does not have yet.
    let files = selected.problem.files();
    let constants: Vec<Term> = live
        .iter()
        .flat_map(|&i| {
            let j = scans[i].joint;
            (0..files).map(move |run| match run {
                0 => Term::new(Effect::Offset, j),
                run => Term {
                    effect: Effect::RunOffset,
                    joint: j,
                    run,
                },
            })
        })
        .collect();
    let extra: Vec<Term> = pairs.iter().chain(&constants).copied().collect();
    let mut terms = selected.selection.terms.clone();
    terms.extend(&extra);
    terms.sort();
    terms.dedup();
    let layout = |s: &[RippleScan]| with_ripple(&selected.problem.layout, s, extra.iter());
    let p0 = Problem::build(base, layout(scans), train, cfg.blocks);
    let subset = p0.independent(&p0.subset(&terms));
    // One weighting for every k, so that the sums compare.
    let w = p0.weights(&subset)?;
    // The sum at the scans' current wavenumbers (the next joint's starting point).
    let mut current = p0.fit(&subset, &w).map_or(f64::INFINITY, |f| f.wsse);
    let at = |s: &[RippleScan]| {
        let p = Problem::build(base, layout(s), train, cfg.blocks);
        p.fit(&subset, &w).map_or(f64::INFINITY, |f| f.wsse)
    };
    for i in live {
        let Some(&(_, span)) = spans.iter().find(|(j, _)| *j == scans[i].joint) else {
            continue;
        };
        let half = std::f64::consts::PI / span;
        let k0 = scans[i].k;
        let mut trial = scans.to_vec();
        let mut sse = |k: f64| {
            trial[i].k = k;
            at(&trial)
        };
        let f0 = current;
        let g = (5f64.sqrt() - 1.0) / 2.0;
        let (mut a, mut b) = ((k0 - half).max(K_MIN), (k0 + half).min(K_MAX));
        let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
        let (mut fc, mut fd) = (sse(c), sse(d));
        for _ in 0..GOLDEN_STEPS {
            if fc < fd {
                (b, d, fd) = (d, c, fc);
                c = b - g * (b - a);
                fc = sse(c);
            } else {
                (a, c, fc) = (c, d, fd);
                d = a + g * (b - a);
                fd = sse(d);
            }
        }
        let (k, f) = if fc < fd { (c, fc) } else { (d, fd) };
        if f < f0 {
            scans[i].k = k;
            current = f;
        }
    }
    Ok(())
}

/// A significant ripple whose pair failed alone, tested with its joint's other candidates of the
/// first stage as one group ([`joint_group`], the family every open candidate): a ripple hides
/// the joint's other effects in their residual and they hide it in its. Kept only when the pair
/// survives the group's pruning; repeated while a group is kept.
fn with_joint_groups(
    p2: &Problem,
    second: &mut Selection,
    pairs: &[Vec<Term>],
    searched: &[Term],
    rules: &Rules,
) -> Result<(), IdentifyError> {
    loop {
        let missed: Vec<usize> = pairs
            .iter()
            .map(|u| u[0].joint)
            .filter(|&j| {
                !second
                    .terms
                    .iter()
                    .any(|t| t.effect.is_ripple() && t.joint == j)
            })
            .collect();
        if missed.is_empty() {
            return Ok(());
        }
        let open = |t: &Term| !second.terms.contains(t);
        let family = pairs.len() + searched.iter().filter(|t| open(t)).count();
        let units: Vec<Vec<Term>> = pairs
            .iter()
            .filter(|u| missed.contains(&u[0].joint))
            .cloned()
            .chain(
                searched
                    .iter()
                    .filter(|t| missed.contains(&t.joint) && open(t))
                    .map(|&t| vec![t]),
            )
            .collect();
        let Some(group) = joint_group(p2, &second.terms, &units, family, rules)? else {
            return Ok(());
        };
        if !group.iter().any(|e| e.term.effect.is_ripple()) {
            return Ok(());
        }
        for ev in group {
            accept(&mut second.terms, &mut second.steps, ev.term, ev);
        }
    }
}

/// Each joint's periodogram peak ([`periodogram_peak`]); a joint of `fixed` that cannot be
/// scanned is an error.
fn scan_joints(
    joints: &[usize],
    samples: &[Samples],
    fixed: &[Term],
    springs: &[usize],
) -> Result<Vec<RippleScan>, IdentifyError> {
    let mut scans = Vec::new();
    for (&joint, (q, r, run)) in joints.iter().zip(samples) {
        let line = springs.contains(&joint);
        match periodogram_peak((q, r, run), (K_MIN, K_MAX), line) {
            Some(peak) => scans.push(RippleScan {
                joint,
                k: peak.k,
                share: peak.share,
                prominence: peak.prominence,
                significant: peak.significant(),
                accepted: false,
            }),
            None if fixed.iter().any(|t| t.joint == joint) => {
                return Err(IdentifyError::Effects(format!(
                    "--effects ripple on joint {}: it moves over less than one period of the \
                     shortest ripple searched (2π/{K_MAX} rad) — drop the ripple terms or give \
                     a motion over a wider range",
                    joint + 1
                )))
            }
            None => {}
        }
    }
    Ok(scans)
}

/// `layout` with the scanned joints' wavenumbers and the ripple `terms` added (sorted; the
/// first-stage model of load-dependent columns moved with the column indices).
fn with_ripple<'a>(
    layout: &Layout,
    scans: &[RippleScan],
    terms: impl Iterator<Item = &'a Term>,
) -> Layout {
    let mut l2 = layout.with_terms(terms);
    for s in scans {
        l2.scales[s.joint] = l2.scales[s.joint].with_ripple(s.k);
    }
    l2
}

#[cfg(test)]
mod tests;
