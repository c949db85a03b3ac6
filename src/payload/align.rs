//! Time alignment of the unloaded twin: the shift that best overlays its joint velocities on
//! the loaded run's (least mean-square difference, coarse search over every lag then a fine one
//! at full rate and a parabola through the best three), then a check that the motions match.

use serde::Serialize;

use super::runs::Run;
use super::PayloadError;

/// Most relative RMS position difference (of a joint's range of motion) accepted after the
/// shift: a twin of the same commanded motion differs only by tracking error, far below this.
pub const MAX_MISMATCH: f64 = 0.05;
/// Least share of the loaded run the shifted twin must cover.
pub const MIN_COVERAGE: f64 = 0.8;

/// Where the twin sits: unloaded time = loaded time + `shift_s`.
#[derive(Debug, Clone, Serialize)]
pub struct Alignment {
    pub shift_s: f64,
    /// Per joint, RMS of `q_loaded − q_unloaded` over the overlap (rad or m).
    pub rms_mismatch: Vec<f64>,
    /// Share of the loaded samples the twin covers.
    pub coverage: f64,
}

/// Both runs' velocities on a uniform grid of step `h`, each joint scaled by the loaded run's
/// RMS velocity so every joint counts alike.
fn velocities(run: &Run, h: f64, scale: &[f64]) -> Vec<Vec<f64>> {
    let (t0, t1) = (run.t[0], run.t[run.len() - 1]);
    let m = ((t1 - t0) / h).floor() as usize + 1;
    (0..m)
        .map(|k| {
            let t = t0 + k as f64 * h;
            (0..run.dof())
                .map(|j| run.at(j, t).map_or(0.0, |s| s.1) / scale[j])
                .collect()
        })
        .collect()
}

/// Mean-square difference of `a[k]` and `b[k + lag]` over their overlap (sampled every `step`),
/// `None` when the overlap is below `min_overlap` samples.
fn cost(a: &[Vec<f64>], b: &[Vec<f64>], lag: i64, step: usize, min_overlap: usize) -> Option<f64> {
    let lo = (-lag).max(0) as usize;
    let hi = (a.len() as i64).min(b.len() as i64 - lag);
    if hi <= lo as i64 || (hi as usize - lo) < min_overlap {
        return None;
    }
    let (mut s, mut n) = (0.0, 0usize);
    for k in (lo..hi as usize).step_by(step) {
        let bk = &b[(k as i64 + lag) as usize];
        s += a[k]
            .iter()
            .zip(bk)
            .map(|(x, y)| (x - y) * (x - y))
            .sum::<f64>();
        n += 1;
    }
    Some(s / n.max(1) as f64)
}

/// The shift of `twin` onto `loaded`, and how well they match after it; an error (saying by how
/// much) when they are not the same motion.
pub fn align(loaded: &Run, twin: &Run) -> Result<Alignment, PayloadError> {
    let n = loaded.dof();
    let dts: Vec<f64> = loaded.t.windows(2).map(|w| w[1] - w[0]).collect();
    let mut sorted = dts.clone();
    sorted.sort_by(f64::total_cmp);
    let h = sorted[sorted.len() / 2];
    let scale: Vec<f64> = (0..n)
        .map(|j| {
            let ms = loaded.dq[j].iter().map(|v| v * v).sum::<f64>() / loaded.len() as f64;
            ms.sqrt().max(1e-9)
        })
        .collect();
    let a = velocities(loaded, h, &scale);
    let b = velocities(twin, h, &scale);
    let min_overlap = (a.len().min(b.len()) as f64 * 0.5) as usize;
    // Coarse: every `step`-th lag with every `step`-th sample (velocities are smooth at this
    // scale), then every lag within two coarse steps of the best.
    let step = (a.len().max(b.len()) / 1500).max(1);
    let (lo, hi) = (-(b.len() as i64), a.len() as i64);
    let best = |lags: &mut dyn Iterator<Item = i64>, step: usize| {
        lags.filter_map(|l| cost(&a, &b, l, step, min_overlap).map(|c| (l, c)))
            .min_by(|x, y| x.1.total_cmp(&y.1))
    };
    // A periodic excitation matches itself one period later too: of the lags whose cost is
    // within a factor 2 of the best (plus noise-level slack), the one with the most overlap.
    let coarse_costs: Vec<(i64, f64)> = (lo..=hi)
        .step_by(step)
        .filter_map(|l| cost(&a, &b, l, step, min_overlap).map(|c| (l, c)))
        .collect();
    let floor = coarse_costs
        .iter()
        .map(|c| c.1)
        .fold(f64::INFINITY, f64::min);
    let overlap = |l: i64| (a.len() as i64).min(b.len() as i64 - l) - (-l).max(0);
    let pick = coarse_costs
        .iter()
        .filter(|c| c.1 <= 2.0 * floor + 1e-3)
        .max_by_key(|c| overlap(c.0))
        .map(|c| (c.0, c.1));
    let Some((coarse, _)) = pick else {
        return Err(PayloadError::Input(format!(
            "{} and {}: the runs cannot overlap by half the shorter one",
            loaded.source, twin.source
        )));
    };
    let span = 2 * step as i64;
    let (lag, c0) = best(&mut (coarse - span..=coarse + span), 1).unwrap_or((coarse, 0.0));
    // Sub-sample: the vertex of the parabola through the costs at lag − 1, lag, lag + 1.
    let frac = match (
        cost(&a, &b, lag - 1, 1, min_overlap),
        cost(&a, &b, lag + 1, 1, min_overlap),
    ) {
        (Some(cm), Some(cp)) if cm + cp - 2.0 * c0 > 0.0 => {
            (0.5 * (cm - cp) / (cm + cp - 2.0 * c0)).clamp(-0.5, 0.5)
        }
        _ => 0.0,
    };
    let shift_s = twin.t[0] - loaded.t[0] + (lag as f64 + frac) * h;

    let mut sq = vec![0.0; n];
    let mut covered = 0usize;
    for (k, &t) in loaded.t.iter().enumerate() {
        let mut row = Vec::with_capacity(n);
        for j in 0..n {
            match twin.at(j, t + shift_s) {
                Some(s) => row.push(s.0),
                None => break,
            }
        }
        if row.len() == n {
            covered += 1;
            for j in 0..n {
                sq[j] += (loaded.q[j][k] - row[j]).powi(2);
            }
        }
    }
    let coverage = covered as f64 / loaded.len() as f64;
    let rms_mismatch: Vec<f64> = sq
        .iter()
        .map(|s| (s / covered.max(1) as f64).sqrt())
        .collect();
    if coverage < MIN_COVERAGE {
        return Err(PayloadError::Mismatch(format!(
            "the unloaded run {} covers only {:.0} % of the loaded run {} after the best shift ({:+.4} s); record the same motion for both",
            twin.source,
            100.0 * coverage,
            loaded.source,
            shift_s
        )));
    }
    for (j, qj) in loaded.q.iter().enumerate() {
        let (min, max) = qj
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        let range = (max - min).max(1e-6);
        let rel = rms_mismatch[j] / range;
        if rel > MAX_MISMATCH {
            return Err(PayloadError::Mismatch(format!(
                "the unloaded run {} does not follow the loaded run {}: after the best shift ({:+.4} s) joint {} differs by {:.4} RMS ({:.1} % of its {:.4} range of motion; at most {:.0} % accepted)",
                twin.source,
                loaded.source,
                shift_s,
                j + 1,
                rms_mismatch[j],
                100.0 * rel,
                range,
                100.0 * MAX_MISMATCH
            )));
        }
    }
    Ok(Alignment {
        shift_s,
        rms_mismatch,
        coverage,
    })
}
