//! **Residual maps** (issue 40): a joint's torque residual `r = τ_measured − τ̂` binned against
//! one variable ([`quantile_map`] for a continuous one, [`category_map`] for the run), each bin
//! with its mean residual and a 95 % confidence band for that mean, and per map a chi-square of
//! the bin means against zero ([`ResidualMap::p_value`]): where the means leave zero beyond their
//! bands, the model misses something that depends on that variable.
//!
//! What is binned ([`super::Outcome::residual_maps`]): the **final model's held-out** residual
//! on the **training** samples, at every `every`-th used raw sample — each sample predicted by
//! the fit without its time block, the prediction whose error the effect search
//! ([`super::select()`]) compares block by block and the guard pools. So a map shows the
//! residual the loop tested, not the in-sample one, from which least squares has already taken
//! every fitted column's own shape (in-sample, a missed effect that a fitted column resembles
//! hides; held out, what that column could not carry to new data stays). The maps are not a
//! gate of the search: on the extended suite's fits of the true effects, in-sample position maps
//! departed from zero (p < 0.01) in 35 % of cases (0 of 23 on effect-free cases) — the
//! vocabulary's columns do not match the simulated shapes exactly.
//!
//! **The band is for autocorrelated residuals.** A residual is correlated in time (filtered
//! states, slow unmodelled effects), so `n` samples in a bin carry less than `n` independent
//! observations. The residual about the map's bin means, `d = r − m(x)`, is modelled as an AR(1)
//! sequence with `ρ` its lag-1 autocorrelation (consecutive samples of one file; clamped to
//! `[0, 1)`). The variance of a bin's mean is then `σ²/n² · Σ_ik ρ^|t_i − t_k|` over the bin's
//! samples (positions `t` in samples; samples of different files uncorrelated), so its effective
//! sample size is `n_eff = n² / Σ_ik ρ^|t_i − t_k|` — for a bin that is one contiguous stretch,
//! `≈ n·(1 − ρ)/(1 + ρ)` ([`ResidualMap::n_eff_factor`]), for scattered samples closer to `n` —
//! kept within `[2, n]`. The band is `mean ± t_{0.975, n_eff−1} · std/√n_eff`.

use serde::Serialize;

use super::ls::t_quantile;

/// Bins of a continuous variable (equal-count; fewer when a bin would hold under
/// [`MIN_PER_BIN`] samples).
pub const BINS: usize = 12;
/// Fewest samples a quantile bin is made for.
pub const MIN_PER_BIN: usize = 20;
/// Smallest effective sample size of a bin (the band of a bin of one sample is not defined).
pub const MIN_N_EFF: f64 = 2.0;

/// What a map bins the residual against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Variable {
    /// The joint's position `q_j`.
    Position,
    /// Its velocity `q̇_j`, signed.
    Velocity,
    /// Its acceleration `q̈_j`.
    Acceleration,
    /// Time since the first sample of the sample's file (a temperature proxy).
    Time,
    /// The training file (run) the sample is from (0-based; one bin each).
    Run,
    /// The joint's own predicted (transmitted) torque `τ̂_j`.
    Torque,
}

impl Variable {
    /// Every variable, in the order the maps are made and plotted.
    pub const ALL: [Variable; 6] = [
        Variable::Position,
        Variable::Velocity,
        Variable::Acceleration,
        Variable::Time,
        Variable::Run,
        Variable::Torque,
    ];

    /// The key in `report.json`.
    pub fn name(self) -> &'static str {
        match self {
            Variable::Position => "q",
            Variable::Velocity => "dq",
            Variable::Acceleration => "ddq",
            Variable::Time => "time",
            Variable::Run => "run",
            Variable::Torque => "tau_hat",
        }
    }

    /// The variable's unit for a revolute (`prismatic` false) or prismatic joint.
    pub fn unit(self, prismatic: bool) -> &'static str {
        match (self, prismatic) {
            (Variable::Position, false) => "rad",
            (Variable::Position, true) => "m",
            (Variable::Velocity, false) => "rad/s",
            (Variable::Velocity, true) => "m/s",
            (Variable::Acceleration, false) => "rad/s^2",
            (Variable::Acceleration, true) => "m/s^2",
            (Variable::Time, _) => "s",
            (Variable::Run, _) => "file index",
            (Variable::Torque, false) => "N·m",
            (Variable::Torque, true) => "N",
        }
    }
}

/// One bin of a map: the variable's range `lo..=hi` and mean (`centre`) over the bin's `n`
/// samples, the residual's mean and standard deviation there, the effective sample size and
/// the 95 % band of the mean (NaN when the bin has under two samples).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Bin {
    pub lo: f64,
    pub hi: f64,
    pub centre: f64,
    pub n: usize,
    pub mean: f64,
    pub std: f64,
    pub n_eff: f64,
    pub ci95_lo: f64,
    pub ci95_hi: f64,
}

/// One joint's residual against one variable (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualMap {
    /// 0-based.
    pub joint: usize,
    pub variable: Variable,
    pub unit: String,
    pub bins: Vec<Bin>,
    /// Lag-1 autocorrelation of the residual about the bin means (clamped to `[0, 1)`).
    pub rho: f64,
    /// `(1 − ρ)/(1 + ρ)`: a contiguous stretch of `n` samples counts as `n` times this.
    pub n_eff_factor: f64,
    /// `Σ (mean/se)²` over the bins with a band, `se = std/√n_eff`.
    pub chi2: f64,
    /// Its degrees of freedom: the bins with a band.
    pub dof: usize,
    /// `P(χ²_dof ≥ chi2)`: small when the bin means leave zero beyond their bands (NaN with no
    /// bin with a band).
    pub p_value: f64,
    /// Why the map is degenerate (a variable that does not vary, too few samples), if it is.
    pub note: Option<String>,
}

/// Every joint's maps of one identification: the final model's training residual at every
/// `every`-th used raw sample of each training file (`samples` in all), per joint one map per
/// [`Variable::ALL`], joint by joint.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ResidualMaps {
    pub every: usize,
    pub samples: usize,
    pub maps: Vec<ResidualMap>,
}

/// The residual `r` against a continuous variable `x`: [`BINS`] equal-count bins (ties kept in
/// one bin; one bin when `x` does not vary). `at[i]` is sample `i`'s (file, position in
/// samples), the samples in time order; non-finite samples are left out.
pub fn quantile_map(
    joint: usize,
    variable: Variable,
    x: &[f64],
    r: &[f64],
    at: &[(usize, u64)],
) -> ResidualMap {
    let mut sorted: Vec<f64> = x
        .iter()
        .zip(r)
        .filter(|(x, r)| x.is_finite() && r.is_finite())
        .map(|(&x, _)| x)
        .collect();
    sorted.sort_by(f64::total_cmp);
    let mut note = None;
    let bins = (sorted.len() / MIN_PER_BIN).clamp(1, BINS);
    // Inner edges at the quantiles k/bins; a bin starts at its edge (an edge is a sample value,
    // so no bin is empty).
    let mut edges: Vec<f64> = (1..bins).map(|k| sorted[k * sorted.len() / bins]).collect();
    edges.dedup();
    if let (Some(&first), Some(&last)) = (sorted.first(), sorted.last()) {
        edges.retain(|&e| e > first);
        if first == last {
            note = Some(format!("{} does not vary: one bin", variable.name()));
        }
    } else {
        note = Some("no finite sample".to_string());
    }
    if sorted.len() < 2 * MIN_PER_BIN && note.is_none() {
        note = Some(format!("only {} samples", sorted.len()));
    }
    let bin_of = |v: f64| edges.partition_point(|&e| e <= v);
    let assign: Vec<Option<usize>> = x
        .iter()
        .zip(r)
        .map(|(&x, &r)| (x.is_finite() && r.is_finite()).then(|| bin_of(x)))
        .collect();
    let mut map = summarise(joint, variable, &assign, edges.len() + 1, x, r, at);
    map.note = note;
    map
}

/// The residual `r` per category `c` (e.g. the run): one bin per category from 0 to the
/// largest, empty ones dropped. `at` as in [`quantile_map`].
pub fn category_map(
    joint: usize,
    variable: Variable,
    c: &[usize],
    r: &[f64],
    at: &[(usize, u64)],
) -> ResidualMap {
    let assign: Vec<Option<usize>> = c
        .iter()
        .zip(r)
        .map(|(&c, r)| r.is_finite().then_some(c))
        .collect();
    let x: Vec<f64> = c.iter().map(|&c| c as f64).collect();
    let count = c.iter().max().map_or(0, |m| m + 1);
    summarise(joint, variable, &assign, count, &x, r, at)
}

/// The map of samples assigned to bins `0..count` (`None`: left out).
fn summarise(
    joint: usize,
    variable: Variable,
    assign: &[Option<usize>],
    count: usize,
    x: &[f64],
    r: &[f64],
    at: &[(usize, u64)],
) -> ResidualMap {
    #[derive(Clone)]
    struct Acc {
        n: usize,
        lo: f64,
        hi: f64,
        sx: f64,
        sr: f64,
    }
    let mut acc = vec![
        Acc {
            n: 0,
            lo: f64::INFINITY,
            hi: f64::NEG_INFINITY,
            sx: 0.0,
            sr: 0.0,
        };
        count
    ];
    for ((b, &x), &r) in assign.iter().zip(x).zip(r) {
        if let Some(a) = b.map(|b| &mut acc[b]) {
            a.n += 1;
            a.lo = a.lo.min(x);
            a.hi = a.hi.max(x);
            a.sx += x;
            a.sr += r;
        }
    }
    let mean: Vec<f64> = acc.iter().map(|a| a.sr / a.n as f64).collect();
    // The residual about the bin means, and its variance per bin.
    let dev: Vec<Option<f64>> = assign
        .iter()
        .zip(r)
        .map(|(b, r)| b.map(|b| r - mean[b]))
        .collect();
    let mut ss = vec![0.0; count];
    for (b, d) in assign.iter().zip(&dev) {
        if let (Some(b), Some(d)) = (b, d) {
            ss[*b] += d * d;
        }
    }
    let rho = lag1(&dev, at);
    let n_eff = bin_n_eff(assign, count, at, rho);
    let (mut chi2, mut dof) = (0.0, 0);
    let mut bins = Vec::new();
    for (b, a) in acc.iter().enumerate().filter(|(_, a)| a.n > 0) {
        let m = mean[b];
        let std = if a.n > 1 {
            (ss[b] / (a.n - 1) as f64).sqrt()
        } else {
            f64::NAN
        };
        let ne = n_eff[b];
        let se = std / ne.sqrt();
        let half = t975(ne - 1.0) * se;
        if se > 0.0 && se.is_finite() {
            chi2 += (m / se).powi(2);
            dof += 1;
        }
        bins.push(Bin {
            lo: a.lo,
            hi: a.hi,
            centre: a.sx / a.n as f64,
            n: a.n,
            mean: m,
            std,
            n_eff: ne,
            ci95_lo: m - half,
            ci95_hi: m + half,
        });
    }
    ResidualMap {
        joint,
        variable,
        unit: variable.unit(false).to_string(),
        bins,
        rho,
        n_eff_factor: (1.0 - rho) / (1.0 + rho),
        chi2,
        dof,
        p_value: if dof > 0 {
            chi2_sf(chi2, dof as f64)
        } else {
            f64::NAN
        },
        note: None,
    }
}

/// Lag-1 autocorrelation of `d` (`None` left out; `at` as in [`quantile_map`]) over pairs of
/// consecutive positions in one file, clamped to `[0, 1)` (a negative one would narrow the band).
pub fn lag1(d: &[Option<f64>], at: &[(usize, u64)]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    let mut prev: Option<(usize, u64, f64)> = None;
    for (&v, &(f, t)) in d.iter().zip(at) {
        let Some(v) = v else {
            prev = None;
            continue;
        };
        den += v * v;
        if let Some((pf, pt, pv)) = prev {
            if pf == f && t == pt + 1 {
                num += v * pv;
            }
        }
        prev = Some((f, t, v));
    }
    let rho = num / den;
    if rho.is_finite() {
        rho.clamp(0.0, 1.0 - 1e-9)
    } else {
        0.0
    }
}

/// Per bin, `n² / Σ_ik ρ^|t_i − t_k|` over its samples, within `[min(2, n), n]`: with the
/// samples in time order, `Σ_ik = n + 2 Σ_k a_k` where `a_k = Σ_{i<k} ρ^(t_k − t_i)` follows
/// `a_k = ρ^(t_k − t_{k−1}) · (a_{k−1} + 1)` (zero across files).
pub fn bin_n_eff(
    assign: &[Option<usize>],
    count: usize,
    at: &[(usize, u64)],
    rho: f64,
) -> Vec<f64> {
    let mut n = vec![0usize; count];
    let mut sum = vec![0.0f64; count];
    let mut last: Vec<Option<(usize, u64, f64)>> = vec![None; count];
    for (b, &(f, t)) in assign.iter().zip(at) {
        let Some(b) = *b else { continue };
        let a = match last[b] {
            Some((lf, lt, la)) if lf == f && rho > 0.0 => {
                rho.powf(t.abs_diff(lt) as f64) * (la + 1.0)
            }
            _ => 0.0,
        };
        n[b] += 1;
        sum[b] += a;
        last[b] = Some((f, t, a));
    }
    n.iter()
        .zip(&sum)
        .map(|(&n, &s)| {
            let n = n as f64;
            (n * n / (n + 2.0 * s)).clamp(MIN_N_EFF.min(n), n)
        })
        .collect()
}

/// Upper 97.5 % quantile of Student's t with `nu` degrees of freedom: exact values below 5
/// (rounded down, so the band errs wide), [`t_quantile`] above.
fn t975(nu: f64) -> f64 {
    const SMALL: [f64; 4] = [12.706, 4.303, 3.182, 2.776];
    if !nu.is_finite() || nu < 1.0 {
        return f64::NAN;
    }
    if nu < 5.0 {
        return SMALL[nu as usize - 1];
    }
    t_quantile(0.975, nu)
}

/// `P(χ²_k ≥ x)`: the regularized upper incomplete gamma function `Q(k/2, x/2)` (series below
/// `a + 1`, Lentz's continued fraction above; Numerical Recipes §6.2).
pub fn chi2_sf(x: f64, k: f64) -> f64 {
    let (a, x) = (k / 2.0, x / 2.0);
    if !(x.is_finite() && a > 0.0) {
        return if x == f64::INFINITY { 0.0 } else { f64::NAN };
    }
    if x <= 0.0 {
        return 1.0;
    }
    let front = (a * x.ln() - x - ln_gamma(a)).exp();
    if x < a + 1.0 {
        let (mut term, mut sum, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..1000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        return (1.0 - sum * front).clamp(0.0, 1.0);
    }
    let tiny = 1e-300;
    let mut b = x + 1.0 - a;
    let mut c = 1.0 / tiny;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..1000 {
        let an = -(i as f64) * (i as f64 - a);
        b += 2.0;
        d = an * d + b;
        if d.abs() < tiny {
            d = tiny;
        }
        c = b + an / c;
        if c.abs() < tiny {
            c = tiny;
        }
        d = 1.0 / d;
        let delta = d * c;
        h *= delta;
        if (delta - 1.0).abs() < 1e-15 {
            break;
        }
    }
    (front * h).clamp(0.0, 1.0)
}

/// `ln Γ(x)`, `x > 0` (Lanczos, g = 7, 9 terms; ~1e-15 relative).
#[allow(clippy::excessive_precision)]
pub(super) fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_93,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_13,
        -176.615_029_162_140_59,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_571_6e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let t = x + 7.5;
    let s = C[1..]
        .iter()
        .enumerate()
        .fold(C[0], |s, (i, &c)| s + c / (x + 1.0 + i as f64));
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + s.ln()
}

#[cfg(test)]
mod tests;
