//! Time alignment of the unloaded twin: the shift that best overlays its joint velocities and
//! positions on the loaded run's (least mean-square difference, coarse search over every lag then
//! a fine one at full rate and a parabola through the best three), then a check that the motions
//! match. Velocities fix the shift sharply; positions tell apart lags that velocities alone
//! confuse (a point-to-point run rests at zero velocity in different postures).

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

/// How each joint's signals are made comparable: velocity divided by the loaded run's RMS
/// velocity, position minus the loaded run's mean divided by its RMS deviation.
struct Scales {
    dq_rms: Vec<f64>,
    q_mean: Vec<f64>,
    q_rms: Vec<f64>,
}

impl Scales {
    fn of(loaded: &Run) -> Scales {
        let len = loaded.len() as f64;
        let mean = |v: &[f64]| v.iter().sum::<f64>() / len;
        let rms = |v: &[f64], m: f64| {
            let ms = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / len;
            ms.sqrt().max(1e-9)
        };
        let q_mean: Vec<f64> = loaded.q.iter().map(|q| mean(q)).collect();
        Scales {
            dq_rms: loaded.dq.iter().map(|dq| rms(dq, 0.0)).collect(),
            q_rms: loaded
                .q
                .iter()
                .zip(&q_mean)
                .map(|(q, m)| rms(q, *m))
                .collect(),
            q_mean,
        }
    }
}

/// A run's scaled velocities, then positions, on a uniform grid of step `h`.
fn signals(run: &Run, h: f64, sc: &Scales) -> Vec<Vec<f64>> {
    let (t0, t1) = (run.t[0], run.t[run.len() - 1]);
    let m = ((t1 - t0) / h).floor() as usize + 1;
    let n = run.dof();
    (0..m)
        .map(|k| {
            let t = t0 + k as f64 * h;
            let s: Vec<_> = (0..n).map(|j| run.at(j, t).unwrap_or_default()).collect();
            let dq = (0..n).map(|j| s[j].1 / sc.dq_rms[j]);
            let q = (0..n).map(|j| (s[j].0 - sc.q_mean[j]) / sc.q_rms[j]);
            dq.chain(q).collect()
        })
        .collect()
}

/// Mean-square difference of `a[k][cols]` and `b[k + lag][cols]` over their overlap (sampled
/// every `step`), `None` when the overlap is below `min_overlap` samples.
fn cost(
    (a, b): (&[Vec<f64>], &[Vec<f64>]),
    cols: std::ops::Range<usize>,
    lag: i64,
    step: usize,
    min_overlap: usize,
) -> Option<f64> {
    let lo = (-lag).max(0) as usize;
    let hi = (a.len() as i64).min(b.len() as i64 - lag);
    if hi <= lo as i64 || (hi as usize - lo) < min_overlap {
        return None;
    }
    let (mut s, mut n) = (0.0, 0usize);
    for k in (lo..hi as usize).step_by(step) {
        let bk = &b[(k as i64 + lag) as usize];
        s += a[k][cols.clone()]
            .iter()
            .zip(&bk[cols.clone()])
            .map(|(x, y)| (x - y) * (x - y))
            .sum::<f64>();
        n += 1;
    }
    Some(s / n.max(1) as f64)
}

/// Of coarse `(lag, cost)` pairs (in lag order), the lag a periodic motion's repeats cannot
/// fool: lags within a factor 2 of the least cost (plus slack at the encoders' noise level) that
/// lie next to each other are one match, counted by its best lag; of the matches, the one with
/// the most `overlap` (then the least cost).
fn coarse_pick(costs: &[(i64, f64)], overlap: impl Fn(i64) -> i64) -> Option<(i64, f64)> {
    let floor = costs.iter().map(|c| c.1).fold(f64::INFINITY, f64::min);
    let mut matches: Vec<(i64, f64)> = Vec::new();
    let mut previous_near = false;
    for &(l, v) in costs {
        let near = v <= 2.0 * floor + 1e-3;
        if near {
            match matches.last_mut() {
                Some(m) if previous_near && v < m.1 => *m = (l, v),
                Some(_) if previous_near => {}
                _ => matches.push((l, v)),
            }
        }
        previous_near = near;
    }
    matches
        .into_iter()
        .max_by(|x, y| overlap(x.0).cmp(&overlap(y.0)).then(y.1.total_cmp(&x.1)))
}

/// The shift of `twin` onto `loaded`, and how well they match after it; an error (saying by how
/// much) when they are not the same motion.
pub fn align(loaded: &Run, twin: &Run) -> Result<Alignment, PayloadError> {
    let n = loaded.dof();
    let dts: Vec<f64> = loaded.t.windows(2).map(|w| w[1] - w[0]).collect();
    let mut sorted = dts.clone();
    sorted.sort_by(f64::total_cmp);
    let h = sorted[sorted.len() / 2];
    let scales = Scales::of(loaded);
    let a = signals(loaded, h, &scales);
    let b = signals(twin, h, &scales);
    let min_overlap = (a.len().min(b.len()) as f64 * 0.5) as usize;
    // Coarse: every `step`-th lag with every `step`-th sample (the signals are smooth at this
    // scale), then every lag within two coarse steps of the best.
    let step = (a.len().max(b.len()) / 1500).max(1);
    let (lo, hi) = (-(b.len() as i64), a.len() as i64);
    let (both, positions) = (0..2 * n, n..2 * n);
    let c = |cols: &std::ops::Range<usize>, l: i64, step: usize| {
        cost((&a, &b), cols.clone(), l, step, min_overlap)
    };
    let best = |lags: &mut dyn Iterator<Item = i64>, step: usize| {
        lags.filter_map(|l| c(&both, l, step).map(|v| (l, v)))
            .min_by(|x, y| x.1.total_cmp(&y.1))
    };
    // A periodic excitation matches itself one period later too (see `coarse_pick`); judged on
    // positions only, as a noisy velocity column would widen the factor.
    let coarse_costs: Vec<(i64, f64)> = (lo..=hi)
        .step_by(step)
        .filter_map(|l| c(&positions, l, step).map(|v| (l, v)))
        .collect();
    let overlap = |l: i64| (a.len() as i64).min(b.len() as i64 - l) - (-l).max(0);
    let pick = coarse_pick(&coarse_costs, overlap);
    let Some((coarse, _)) = pick else {
        return Err(PayloadError::Input(format!(
            "{} and {}: the runs cannot overlap by half the shorter one",
            loaded.source, twin.source
        )));
    };
    let span = 2 * step as i64;
    let (lag, c0) = best(&mut (coarse - span..=coarse + span), 1).unwrap_or((coarse, 0.0));
    // Sub-sample: the vertex of the parabola through the costs at lag − 1, lag, lag + 1.
    let frac = match (c(&both, lag - 1, 1), c(&both, lag + 1, 1)) {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A one-joint run on `t0 + k/fs`: position `q(t)`, velocity `q'(t)` plus `noise(k)`.
    fn run(t0: f64, secs: f64, q: impl Fn(f64) -> (f64, f64), noise: impl Fn(usize) -> f64) -> Run {
        let fs = 200.0;
        let t: Vec<f64> = (0..(secs * fs) as usize)
            .map(|k| t0 + k as f64 / fs)
            .collect();
        let (mut pos, mut vel) = (Vec::new(), Vec::new());
        for (k, &tk) in t.iter().enumerate() {
            let (p, v) = q(tk);
            pos.push(p);
            vel.push(v + noise(k));
        }
        Run {
            source: format!("run@{t0}"),
            tau: vec![vec![0.0; t.len()]],
            ddq: vec![vec![0.0; t.len()]],
            q: vec![pos],
            dq: vec![vel],
            t,
            filter: None,
            cutoff_hz: None,
        }
    }

    /// Point to point: a smooth 1 rad step every 4 s (0.8 s of motion), resting between, so the
    /// positions climb a staircase while the velocity repeats the same bump.
    fn staircase(t: f64) -> (f64, f64) {
        let (period, rise) = (4.0, 0.8);
        let steps = (t / period).floor();
        let x = ((t - steps * period) / rise).clamp(0.0, 1.0);
        let s = x * x * (3.0 - 2.0 * x);
        let ds = if x > 0.0 && x < 1.0 {
            6.0 * x * (1.0 - x) / rise
        } else {
            0.0
        };
        (steps + s, ds)
    }

    /// A deterministic, white-looking noise of standard deviation about `sd`.
    fn noise(sd: f64) -> impl Fn(usize) -> f64 {
        move |k| sd * 3.0_f64.sqrt() * (2.0 * ((k as f64 * 0.618_033_988_75).fract()) - 1.0)
    }

    #[test]
    fn a_point_to_point_twin_with_a_noisy_velocity_column_is_placed_by_its_positions() {
        // Velocity noise twice the motion's RMS velocity: the velocity cost's floor is so high
        // that lags a whole step apart fall within its factor 2; the positions tell them apart.
        let loaded = run(0.0, 40.0, staircase, noise(1.0));
        let twin = run(-0.55, 42.0, staircase, noise(1.0));
        let a = align(&loaded, &twin).unwrap();
        // The true shift is 0: the twin's samples are the same motion on their own clock.
        assert!(a.shift_s.abs() < 0.02, "shift {}", a.shift_s);
        assert!(a.rms_mismatch[0] < 0.01, "mismatch {:?}", a.rms_mismatch);
    }

    #[test]
    fn a_periodic_twin_takes_the_lag_with_the_most_overlap() {
        // Velocity and position repeat every 2 s: a lag of one period matches as well, with less
        // overlap; the true lag (0.3 s) overlaps most.
        let w = std::f64::consts::PI;
        let wave = |t: f64| ((w * t).sin(), w * (w * t).cos());
        let loaded = run(0.0, 20.0, wave, noise(0.0));
        let twin = run(-0.3, 20.0, wave, noise(0.0));
        let a = align(&loaded, &twin).unwrap();
        assert!(a.shift_s.abs() < 1e-3, "shift {}", a.shift_s);
    }
}
