//! Excitation design: a binary-coded genetic algorithm ([`minimize`]) and the two problems it
//! solves — the paper's Logistic step-by-step design ([`LogisticProblem`], eq. 17) and a
//! Swevers-type Fourier series under the same motion constraints ([`FourierProblem`]).
//!
//! The GA is the paper's: each variable coded on `bits` bits, roulette selection with probability
//! ∝ 1/H, single-point crossover with probability `crossover`, bit-flip mutation with probability
//! `mutation`; we add elitism (the best individual survives), which the paper does not mention
//! but which makes the reported best monotone. It is seeded (ChaCha8) and evaluates the population
//! in parallel with rayon, so a seed gives the same result on any number of threads.
//!
//! ```
//! use dynid::excitation::{minimize, GaConfig};
//! let cfg = GaConfig { generations: 60, ..GaConfig::default() };
//! let r = minimize(&cfg, &[(-2.0, 2.0), (-2.0, 2.0)], |x| 1.0 + (x[0] - 0.5).powi(2) + (x[1] + 1.0).powi(2), None);
//! assert!((r.best[0] - 0.5).abs() < 0.1 && (r.best[1] + 1.0).abs() < 0.1);
//! ```
//!
//! Design for any arm under its own limits (`dynid excite`) lives in the submodules, one piece per
//! file: [`limits`] (where the limits come from), [`derived`] (acceleration limits from effort and
//! inertia), [`fourier_quintic`](crate::trajectory::fourier_quintic) and [`logistic_n`](crate::trajectory::logistic_n) (the
//! families), [`objective`] (the observation matrix), [`cmaes`] (the optimiser), [`design`] (the
//! problem and its checks) and [`output`] (the files written).

pub mod cmaes;
pub mod derived;
pub mod design;
pub mod limits;
pub mod objective;
pub mod output;

use nalgebra::{DMatrix, SymmetricEigen};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::model::Model;
use crate::trajectory::fourier::{Fourier, FourierJoint};
use crate::trajectory::logistic::{JointMotion, Logistic, LogisticJoint};
use crate::trajectory::{sample, Motion, TrajectoryError};

/// Genetic-algorithm settings (defaults are the paper's).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GaConfig {
    pub bits: u32,
    pub population: usize,
    pub crossover: f64,
    pub mutation: f64,
    pub generations: usize,
    pub seed: u64,
}

impl Default for GaConfig {
    fn default() -> Self {
        Self {
            bits: 20,
            population: 40,
            crossover: 0.5,
            mutation: 0.01,
            generations: 500,
            seed: 2022,
        }
    }
}

/// Outcome of [`minimize`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GaResult {
    /// Decoded best variables.
    pub best: Vec<f64>,
    /// Its cost `H`.
    pub cost: f64,
    /// Best cost after each generation.
    pub history: Vec<f64>,
    /// Number of cost evaluations.
    pub evaluations: usize,
}

fn decode(genes: &[u32], bounds: &[(f64, f64)], bits: u32) -> Vec<f64> {
    let top = ((1u64 << bits) - 1) as f64;
    genes
        .iter()
        .zip(bounds)
        .map(|(&g, &(lo, hi))| lo + (hi - lo) * g as f64 / top)
        .collect()
}

/// Minimises `cost` (which must be ≥ 0; `H` in the paper, selection ∝ 1/H) over the box `bounds`.
pub fn minimize<F>(
    cfg: &GaConfig,
    bounds: &[(f64, f64)],
    cost: F,
    progress: Option<&crate::progress::Progress>,
) -> GaResult
where
    F: Fn(&[f64]) -> f64 + Sync,
{
    let bits = cfg.bits.clamp(1, 31);
    let mask = (1u32 << bits) - 1;
    let nv = bounds.len();
    let total_bits = nv * bits as usize;
    let pop = cfg.population.max(2);
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let mut genes: Vec<Vec<u32>> = (0..pop)
        .map(|_| (0..nv).map(|_| rng.gen::<u32>() & mask).collect())
        .collect();
    let eval = |g: &Vec<Vec<u32>>| -> Vec<f64> {
        g.par_iter()
            .map(|c| {
                let h = cost(&decode(c, bounds, bits));
                if h.is_finite() {
                    h.max(0.0)
                } else {
                    f64::MAX
                }
            })
            .collect()
    };
    let mut costs = eval(&genes);
    let mut evaluations = pop;
    let mut history = Vec::with_capacity(cfg.generations);
    let argmin = |c: &[f64]| (0..c.len()).fold(0, |b, i| if c[i] < c[b] { i } else { b });

    for _ in 0..cfg.generations {
        let elite = argmin(&costs);
        // roulette wheel on 1/H
        let fit: Vec<f64> = costs.iter().map(|&h| 1.0 / (h + 1e-12)).collect();
        let total: f64 = fit.iter().sum();
        let mut next: Vec<Vec<u32>> = Vec::with_capacity(pop);
        next.push(genes[elite].clone());
        while next.len() < pop {
            let mut pick = || {
                let mut r = rng.gen::<f64>() * total;
                for (i, f) in fit.iter().enumerate() {
                    r -= f;
                    if r <= 0.0 {
                        return i;
                    }
                }
                pop - 1
            };
            let (pa, pb) = (pick(), pick());
            let (mut a, mut b) = (genes[pa].clone(), genes[pb].clone());
            if rng.gen::<f64>() < cfg.crossover && total_bits > 1 {
                let cut = rng.gen_range(1..total_bits);
                crossover(&mut a, &mut b, cut, bits);
            }
            for c in [&mut a, &mut b] {
                for g in c.iter_mut() {
                    for bit in 0..bits {
                        if rng.gen::<f64>() < cfg.mutation {
                            *g ^= 1 << bit;
                        }
                    }
                }
            }
            next.push(a);
            if next.len() < pop {
                next.push(b);
            }
        }
        genes = next;
        costs = eval(&genes);
        evaluations += pop;
        history.push(costs[argmin(&costs)]);
        if let Some(pb) = progress {
            pb.step();
        }
    }
    let best = argmin(&costs);
    GaResult {
        best: decode(&genes[best], bounds, bits),
        cost: costs[best],
        history,
        evaluations,
    }
}

/// Swaps all bits at positions ≥ `cut` of the concatenated chromosomes (most significant bit of
/// variable 0 first).
fn crossover(a: &mut [u32], b: &mut [u32], cut: usize, bits: u32) {
    let bits_us = bits as usize;
    for v in 0..a.len() {
        let start = v * bits_us;
        let end = start + bits_us;
        if end <= cut {
            continue;
        }
        let low = if cut <= start { bits_us } else { end - cut };
        let m = if low >= 32 {
            u32::MAX
        } else {
            (1u32 << low) - 1
        };
        let (x, y) = (a[v] & m, b[v] & m);
        a[v] = (a[v] & !m) | y;
        b[v] = (b[v] & !m) | x;
    }
}

/// Points along a moving joint's range at which the end-effector height is checked.
const HEIGHT_GRID: usize = 256;

/// Motion limits (the paper's: `0 < q < π`, `|q̇| < π/6`, `|q̈| < π/15`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Limits {
    pub q_min: f64,
    pub q_max: f64,
    pub dq_max: f64,
    pub ddq_max: f64,
}

impl Limits {
    pub fn paper() -> Self {
        use std::f64::consts::PI;
        Self {
            q_min: 0.0,
            q_max: PI,
            dq_max: PI / 6.0,
            ddq_max: PI / 15.0,
        }
    }
}

/// End-effector height above the ground as a function of `q` (the "above the ground" constraint).
pub type HeightFn = fn(&[f64], &[f64]) -> f64;

/// One step of a step-by-step experiment: joint `joint` moves, the others rest; least squares on
/// equation `row` of the base regressor for the base parameters `cols` (the others are known).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepPlan {
    pub joint: usize,
    pub row: usize,
    pub cols: Vec<usize>,
}

impl StepPlan {
    /// The paper's plan for `planar2`: step 1 moves joint 2 and identifies θ4..6 from equation 2
    /// (`Q`), step 2 moves joint 1 and identifies θ1..3 from equation 1 (`M`).
    pub fn paper() -> Vec<StepPlan> {
        vec![
            StepPlan {
                joint: 1,
                row: 1,
                cols: vec![3, 4, 5],
            },
            StepPlan {
                joint: 0,
                row: 0,
                cols: vec![0, 1, 2],
            },
        ]
    }
}

/// Condition number `σ_max/σ_min` of a tall matrix from its Gram matrix (`∞` if singular).
pub fn cond_from_gram(gram: &DMatrix<f64>) -> f64 {
    let eig = SymmetricEigen::new(gram.clone()).eigenvalues;
    let (lo, hi) = eig
        .iter()
        .fold((f64::MAX, 0.0_f64), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    if lo > hi * 1e-300 && lo > 0.0 {
        (hi / lo).sqrt()
    } else {
        f64::INFINITY
    }
}

/// Margins of every constraint (positive = satisfied).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Margins {
    /// Per moving joint: `min q − q_min`.
    pub q_low: Vec<f64>,
    /// Per moving joint: `q_max − max q`.
    pub q_high: Vec<f64>,
    /// Per moving joint: `dq_max − max |q̇|`.
    pub velocity: Vec<f64>,
    /// Per moving joint: `ddq_max − max |q̈|`.
    pub acceleration: Vec<f64>,
    /// Lowest end-effector height over all steps (if a height function was given).
    pub height: Option<f64>,
    /// Per moving joint: `T/4 − δ·Ts` (the sample window must fit inside its half period).
    pub window: Vec<f64>,
    /// Per moving joint: `tol − max(|q̇|, |q̈|)` at the start, splice and end points (eq. 11).
    pub rest: Vec<f64>,
}

impl Margins {
    /// Sum of the violations, each relative to its limit (0 when feasible).
    pub fn violation(&self, l: &Limits) -> f64 {
        let range = (l.q_max - l.q_min).abs().max(1e-12);
        let neg = |v: &[f64], scale: f64| v.iter().map(|&m| (-m).max(0.0) / scale).sum::<f64>();
        neg(&self.q_low, range)
            + neg(&self.q_high, range)
            + neg(&self.velocity, l.dq_max.abs().max(1e-12))
            + neg(&self.acceleration, l.ddq_max.abs().max(1e-12))
            + self.height.map_or(0.0, |h| (-h).max(0.0))
    }

    /// Whether every margin is positive.
    pub fn feasible(&self) -> bool {
        let all = [
            &self.q_low,
            &self.q_high,
            &self.velocity,
            &self.acceleration,
            &self.window,
            &self.rest,
        ];
        all.iter().all(|v| v.iter().all(|&m| m > 0.0)) && self.height.is_none_or(|h| h >= 0.0)
    }
}

/// A Logistic design: per joint `A`, `w`, `δ` (samples), and the derived period.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LogisticDesign {
    pub a: Vec<f64>,
    pub w: Vec<f64>,
    /// Half-width of the sample window around each transition midpoint, in samples of `Ts`.
    pub delta: Vec<usize>,
    /// Period of each joint (from eq. 11).
    pub period: Vec<f64>,
}

/// Evaluation of a design: the condition number of each step's regressor block and the margins.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LogisticEval {
    pub cond: Vec<f64>,
    pub margins: Margins,
    /// `Σ cond + penalty·[infeasible]` (eq. 17).
    pub cost: f64,
}

/// End-effector height of a planar 2-link arm above its base, `geometry = [a1, a2]` (a
/// [`HeightFn`] for the "above the ground" constraint).
pub fn planar_height(q: &[f64], geometry: &[f64]) -> f64 {
    geometry[0] * q[0].sin() + geometry[1] * (q[0] + q[1]).sin()
}

/// `a1` of a generated arm from its D-H table (joint 2's `a`; 1 when there is none).
pub fn link1_length(model: &dyn Model) -> f64 {
    crate::dh::DhTable::from_str(model.arm_toml(), model.name())
        .ok()
        .and_then(|t| t.joints.get(1).map(|j| j.a))
        .unwrap_or(1.0)
}

/// Settings of the paper's Logistic design on a planar 2-DOF arm (defaults: the paper's; the
/// reproduction's `PaperConfig` carries the same fields).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogisticSettings {
    pub limits: Limits,
    /// Grid the periods are rounded up to, s.
    pub period_grid: f64,
    /// Eq. 11 tolerance on `|q̇|`, `|q̈|` at start, end and splice points.
    pub rest_tol: f64,
    /// GA box: `A`, `w` and `δ` (samples).
    pub a_range: (f64, f64),
    pub w_range: (f64, f64),
    pub delta_range: (f64, f64),
    /// Length of link 2 for the "above the ground" constraint (the D-H table has no tool frame), m.
    pub link2_length: f64,
}

impl LogisticSettings {
    /// The paper's values.
    pub fn paper() -> Self {
        Self {
            limits: Limits::paper(),
            period_grid: 0.04,
            rest_tol: 1e-4,
            a_range: (0.05, std::f64::consts::PI),
            w_range: (0.05, 3.0),
            delta_range: (1.0, 1500.0),
            link2_length: 1.0,
        }
    }
}

/// The paper's excitation problem (eq. 17) for a step plan on any arm.
pub struct LogisticProblem<'a> {
    pub model: &'a dyn Model,
    pub steps: Vec<StepPlan>,
    /// Start (rest) position of every joint; a moving joint's offset `h`.
    pub start: Vec<f64>,
    pub limits: Limits,
    pub height: Option<HeightFn>,
    /// Geometry passed to `height` (e.g. link lengths).
    pub geometry: Vec<f64>,
    /// Sample time of the identification log, s (δ counts samples of this).
    pub ts: f64,
    /// Grid the periods are rounded up to, s.
    pub grid: f64,
    /// Eq. 11 tolerance.
    pub rest_tol: f64,
    /// Added to the cost of an infeasible design (ε in eq. 17).
    pub penalty: f64,
    /// GA box: `A`, `w` and `δ` (samples).
    pub a_range: (f64, f64),
    pub w_range: (f64, f64),
    pub delta_range: (f64, f64),
}

impl<'a> LogisticProblem<'a> {
    /// The paper's step-by-step problem ([`StepPlan::paper`]) on a planar 2-DOF arm resting at
    /// `q = 0`, with the "above the ground" constraint, sampled every `ts` s.
    pub fn planar(model: &'a dyn Model, s: &LogisticSettings, ts: f64) -> Self {
        LogisticProblem {
            model,
            steps: StepPlan::paper(),
            start: vec![0.0; 2],
            limits: s.limits,
            height: Some(planar_height),
            geometry: vec![link1_length(model), s.link2_length],
            ts,
            grid: s.period_grid,
            rest_tol: s.rest_tol,
            penalty: 1000.0,
            a_range: s.a_range,
            w_range: s.w_range,
            delta_range: s.delta_range,
        }
    }
}

impl LogisticProblem<'_> {
    /// Joints that move in some step, in joint order (the order of the design vectors).
    pub fn moving(&self) -> Vec<usize> {
        let mut j: Vec<usize> = self.steps.iter().map(|s| s.joint).collect();
        j.sort_unstable();
        j.dedup();
        j
    }

    /// GA box for `[A…, w…, δ…]` over the moving joints.
    pub fn bounds(&self) -> Vec<(f64, f64)> {
        let m = self.moving().len();
        let mut b = vec![self.a_range; m];
        b.extend(vec![self.w_range; m]);
        b.extend(vec![self.delta_range; m]);
        b
    }

    /// Builds the design from a GA vector `[A…, w…, δ…]`.
    pub fn design(&self, x: &[f64]) -> Result<LogisticDesign, TrajectoryError> {
        let m = self.moving().len();
        let (a, w) = (x[..m].to_vec(), x[m..2 * m].to_vec());
        let delta = x[2 * m..3 * m]
            .iter()
            .map(|d| d.round().max(0.0) as usize)
            .collect();
        let period = (0..m)
            .map(|i| {
                LogisticJoint::resting_ends(a[i], w[i], 0.0, self.rest_tol, self.grid)
                    .map(|j| j.period)
            })
            .collect::<Result<_, _>>()?;
        Ok(LogisticDesign {
            a,
            w,
            delta,
            period,
        })
    }

    /// The trajectory of step `s` of `design`: its joint moves for one period, the others rest.
    pub fn step_trajectory(&self, design: &LogisticDesign, s: usize) -> Logistic {
        let moving = self.moving();
        let step = &self.steps[s];
        let i = moving.iter().position(|&j| j == step.joint).unwrap_or(0);
        let joints = self
            .start
            .iter()
            .enumerate()
            .map(|(j, &q0)| {
                if j == step.joint {
                    JointMotion::Logistic(LogisticJoint {
                        a: design.a[i],
                        w: design.w[i],
                        h: q0,
                        period: design.period[i],
                    })
                } else {
                    JointMotion::Rest(q0)
                }
            })
            .collect();
        Logistic { joints, periods: 1 }
    }

    /// Sample indices (of the `Ts` log of one period) inside the ±δ windows around both midpoints.
    pub fn window(&self, joint: &LogisticJoint, delta: usize) -> Vec<usize> {
        let n = (joint.period / self.ts).round() as usize;
        let mut idx = Vec::new();
        for mid in joint.midpoints(0) {
            let c = (mid / self.ts).round() as i64;
            for k in c - delta as i64..=c + delta as i64 {
                if k >= 0 && (k as usize) < n {
                    idx.push(k as usize);
                }
            }
        }
        idx
    }

    /// Condition numbers and margins of a design.
    pub fn evaluate(&self, d: &LogisticDesign) -> LogisticEval {
        let moving = self.moving();
        let nb = self.model.nb();
        let dof = self.model.dof();
        let mut yb = vec![0.0; dof * nb];
        let mut margins = Margins {
            q_low: vec![],
            q_high: vec![],
            velocity: vec![],
            acceleration: vec![],
            height: self.height.map(|_| f64::INFINITY),
            window: vec![],
            rest: vec![],
        };
        for (i, &j) in moving.iter().enumerate() {
            let l = LogisticJoint {
                a: d.a[i],
                w: d.w[i],
                h: self.start[j],
                period: d.period[i],
            };
            // the logistic never reaches h or h + A: its range is (h, h + A) up to e^{-wT/4}
            let (q_lo, _, _) = l.eval(0.0);
            margins.q_low.push(q_lo - self.limits.q_min);
            margins.q_high.push(self.limits.q_max - (l.h + l.a));
            margins
                .velocity
                .push(self.limits.dq_max - l.peak_velocity());
            margins
                .acceleration
                .push(self.limits.ddq_max - l.peak_acceleration());
            margins
                .window
                .push(0.25 * l.period - d.delta[i] as f64 * self.ts);
            let worst = [0.0, 0.5 * l.period, l.period]
                .iter()
                .flat_map(|&t| [l.eval(t), l.eval(t - 1e-9 * l.period)])
                .map(|(_, v, a)| v.abs().max(a.abs()))
                .fold(0.0, f64::max);
            margins.rest.push(self.rest_tol - worst);
        }
        let mut cond = Vec::with_capacity(self.steps.len());
        let (mut q, mut dq, mut ddq) = (vec![0.0; dof], vec![0.0; dof], vec![0.0; dof]);
        for (s, step) in self.steps.iter().enumerate() {
            let traj = self.step_trajectory(d, s);
            let i = moving.iter().position(|&j| j == step.joint).unwrap_or(0);
            let lj = match traj.moving(step.joint) {
                Some(l) => *l,
                None => continue,
            };
            // Each transition is monotone between h and h + A while the other joints rest, so
            // the configurations visited are exactly that segment: check the height along it.
            if let (Some(hf), Some(h)) = (self.height, margins.height.as_mut()) {
                q.copy_from_slice(&self.start);
                for k in 0..=HEIGHT_GRID {
                    q[step.joint] = lj.h + lj.a * k as f64 / HEIGHT_GRID as f64;
                    *h = h.min(hf(&q, &self.geometry));
                }
            }
            let nc = step.cols.len();
            let mut gram = DMatrix::<f64>::zeros(nc, nc);
            for k in self.window(&lj, d.delta[i]) {
                traj.eval(k as f64 * self.ts, &mut q, &mut dq, &mut ddq);
                self.model.base_regressor(&q, &dq, &ddq, &mut yb);
                let row = &yb[step.row * nb..(step.row + 1) * nb];
                for a in 0..nc {
                    for b in 0..=a {
                        gram[(a, b)] += row[step.cols[a]] * row[step.cols[b]];
                    }
                }
            }
            for a in 0..nc {
                for b in 0..a {
                    gram[(b, a)] = gram[(a, b)];
                }
            }
            cond.push(cond_from_gram(&gram));
        }
        let feasible = margins.feasible();
        let mut cost: f64 = cond.iter().sum();
        if !feasible {
            cost += self.penalty;
        }
        LogisticEval {
            cond,
            margins,
            cost,
        }
    }

    /// GA cost of a vector `[A…, w…, δ…]`.
    pub fn cost(&self, x: &[f64]) -> f64 {
        match self.design(x) {
            Ok(d) => {
                let c = self.evaluate(&d).cost;
                if c.is_finite() {
                    c
                } else {
                    1e12
                }
            }
            Err(_) => 1e12,
        }
    }
}

/// Fourier-series excitation under the same limits: per joint the offset `q_i0` and the
/// coefficients `a_3..a_N`, `b_2..b_N` are free; `a_1`, `a_2`, `b_1` are solved so the motion starts
/// at rest (`q̇(0) = q̈(0) = 0`). The cost is the condition number of the full stacked base
/// regressor (all joints move at once) plus the penalty if a limit is violated.
pub struct FourierProblem<'a> {
    pub model: &'a dyn Model,
    pub limits: Limits,
    pub height: Option<HeightFn>,
    pub geometry: Vec<f64>,
    /// Fundamental angular frequency, rad/s.
    pub wf: f64,
    /// Harmonics per joint (≥ 2).
    pub harmonics: usize,
    /// Bound on every free coefficient (rad/s).
    pub coef_bound: f64,
    /// Sample time used to evaluate the cost and the limits.
    pub ts: f64,
    pub penalty: f64,
}

/// Evaluation of a Fourier design.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FourierEval {
    pub cond: f64,
    pub margins: Margins,
    pub cost: f64,
}

impl FourierProblem<'_> {
    fn per_joint(&self) -> usize {
        // q0, a_2..a_N, b_2..b_N
        1 + 2 * (self.harmonics - 1)
    }

    /// GA box `[q0, a_2..a_N, b_2..b_N]` per joint (`a_1`, `b_1` are solved from the rest start).
    pub fn bounds(&self) -> Vec<(f64, f64)> {
        let mut b = Vec::new();
        for _ in 0..self.model.dof() {
            b.push((self.limits.q_min, self.limits.q_max));
            b.extend(vec![
                (-self.coef_bound, self.coef_bound);
                2 * (self.harmonics - 1)
            ]);
        }
        b
    }

    /// The trajectory for a GA vector (one period).
    pub fn trajectory(&self, x: &[f64]) -> Fourier {
        let p = self.per_joint();
        let nh = self.harmonics - 1;
        let joints = (0..self.model.dof())
            .map(|j| {
                let v = &x[j * p..(j + 1) * p];
                FourierJoint::starting_at_rest(self.wf, &v[1..1 + nh], &v[1 + nh..1 + 2 * nh], v[0])
            })
            .collect();
        Fourier { joints, periods: 1 }
    }

    /// Condition number and margins of a trajectory, sampled every `ts`. The cost counts a design
    /// as feasible only if it stays within the limits between the samples too ([`between_samples`]):
    /// the best design sits on a limit, and a coarse grid (the GA's) misses the peaks between its
    /// points — a design feasible on the GA's 20 Hz grid was 1.2e-4 rad/s² over the acceleration
    /// limit on the log's grid. The margins are the sampled ones.
    pub fn evaluate(&self, f: &Fourier) -> FourierEval {
        let dof = self.model.dof();
        let nb = self.model.nb();
        let smp = sample(f, self.ts, false);
        let mut gram = DMatrix::<f64>::zeros(nb, nb);
        let mut yb = vec![0.0; dof * nb];
        let (mut lo, mut hi, mut vmax, mut amax) = (
            vec![f64::MAX; dof],
            vec![f64::MIN; dof],
            vec![0.0_f64; dof],
            vec![0.0_f64; dof],
        );
        let mut height = self.height.map(|_| f64::INFINITY);
        for k in 0..smp.t.len() {
            let r = k * dof..(k + 1) * dof;
            let (q, dq, ddq) = (&smp.q[r.clone()], &smp.dq[r.clone()], &smp.ddq[r]);
            for j in 0..dof {
                lo[j] = lo[j].min(q[j]);
                hi[j] = hi[j].max(q[j]);
                vmax[j] = vmax[j].max(dq[j].abs());
                amax[j] = amax[j].max(ddq[j].abs());
            }
            if let (Some(hf), Some(h)) = (self.height, height.as_mut()) {
                *h = h.min(hf(q, &self.geometry));
            }
            self.model.base_regressor(q, dq, ddq, &mut yb);
            for row in yb.chunks_exact(nb) {
                for a in 0..nb {
                    for b in 0..=a {
                        gram[(a, b)] += row[a] * row[b];
                    }
                }
            }
        }
        for a in 0..nb {
            for b in 0..a {
                gram[(b, a)] = gram[(a, b)];
            }
        }
        let l = &self.limits;
        let margins = Margins {
            q_low: lo.iter().map(|v| v - l.q_min).collect(),
            q_high: hi.iter().map(|v| l.q_max - v).collect(),
            velocity: vmax.iter().map(|v| l.dq_max - v).collect(),
            acceleration: amax.iter().map(|v| l.ddq_max - v).collect(),
            height,
            window: vec![],
            rest: vec![],
        };
        let cond = cond_from_gram(&gram);
        let mut cost = if cond.is_finite() { cond } else { 1e12 };
        let guarded = between_samples(f, &margins, self.ts);
        if !guarded.feasible() {
            // Graded (unlike eq. 17's flat ε): a random Fourier series is almost never feasible,
            // and a flat penalty would leave the GA blind; the grade points it to the feasible set.
            cost += self.penalty * (1.0 + guarded.violation(&self.limits));
        }
        FourierEval {
            cond,
            margins,
            cost,
        }
    }

    /// GA cost of a vector.
    pub fn cost(&self, x: &[f64]) -> f64 {
        self.evaluate(&self.trajectory(x)).cost
    }
}

/// `margins` of `f` sampled every `ts`, less the most each signal can rise between two samples:
/// at a maximum of `|x|` between samples `x' = 0`, and a sample lies within `ts/2`, so the sampled
/// maximum is short by at most `sup|x''|·ts²/8`; `sup|x''|` is bounded by the series' coefficients
/// (velocity amplitude `|(a_k, b_k)|` of harmonic `k` at `w_k`: `Σ|·|w_k` for `q`, `Σ|·|w_k²` for
/// `q̇`, `Σ|·|w_k³` for `q̈`). The height margin is left as sampled.
pub fn between_samples(f: &Fourier, margins: &Margins, ts: f64) -> Margins {
    let bound = |j: &FourierJoint, power: i32| {
        (0..j.harmonics())
            .map(|k| {
                let wk = j.wf * (k + 1) as f64;
                let (a, b) = (
                    j.a.get(k).copied().unwrap_or(0.0),
                    j.b.get(k).copied().unwrap_or(0.0),
                );
                a.hypot(b) * wk.powi(power)
            })
            .sum::<f64>()
            * ts
            * ts
            / 8.0
    };
    let less = |m: &[f64], power: i32| -> Vec<f64> {
        m.iter()
            .zip(&f.joints)
            .map(|(&m, j)| m - bound(j, power))
            .collect()
    };
    Margins {
        q_low: less(&margins.q_low, 1),
        q_high: less(&margins.q_high, 1),
        velocity: less(&margins.velocity, 2),
        acceleration: less(&margins.acceleration, 3),
        ..margins.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`between_samples`] is a lower bound on the margins between the samples: for random series,
    /// the GA grid's guarded margins never exceed those sampled 100× finer (the oracle: dense
    /// sampling of the same series), and they are strictly below the coarse grid's own.
    #[test]
    fn guarded_margins_bound_the_margins_between_samples() {
        let model = crate::arms::find("planar2").expect("planar2");
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let problem = |ts: f64| FourierProblem {
            model,
            limits: Limits::paper(),
            height: None,
            geometry: vec![],
            wf: std::f64::consts::TAU / 10.0,
            harmonics: 5,
            coef_bound: 0.5,
            ts,
            penalty: 1000.0,
        };
        let (coarse, fine) = (problem(0.05), problem(0.0005));
        for _ in 0..20 {
            let bounds = coarse.bounds();
            let x: Vec<f64> = bounds
                .iter()
                .map(|&(lo, hi)| rng.gen_range(lo..hi))
                .collect();
            let f = coarse.trajectory(&x);
            let sampled = coarse.evaluate(&f).margins;
            let guarded = between_samples(&f, &sampled, coarse.ts);
            let dense = fine.evaluate(&f).margins;
            let pairs = [
                (&guarded.q_low, &dense.q_low, &sampled.q_low),
                (&guarded.q_high, &dense.q_high, &sampled.q_high),
                (&guarded.velocity, &dense.velocity, &sampled.velocity),
                (
                    &guarded.acceleration,
                    &dense.acceleration,
                    &sampled.acceleration,
                ),
            ];
            for (g, d, s) in pairs {
                for j in 0..g.len() {
                    assert!(g[j] <= d[j] + 1e-12, "guarded {} > dense {}", g[j], d[j]);
                    assert!(g[j] < s[j], "no guard: {} vs {}", g[j], s[j]);
                }
            }
        }
    }

    #[test]
    fn crossover_swaps_the_tail_bits() {
        let (mut a, mut b) = (vec![0u32, 0], vec![0xF, 0xF]);
        // 4 bits per variable, cut after bit 6 of 8: the last two bits of variable 1 swap
        crossover(&mut a, &mut b, 6, 4);
        assert_eq!(a, vec![0, 0b0011]);
        assert_eq!(b, vec![0xF, 0b1100]);
        let (mut a, mut b) = (vec![0u32, 0], vec![0xF, 0xF]);
        crossover(&mut a, &mut b, 2, 4);
        assert_eq!(a, vec![0b0011, 0xF]);
        assert_eq!(b, vec![0b1100, 0]);
    }

    #[test]
    fn decode_hits_both_bounds() {
        let x = decode(&[0, (1 << 20) - 1], &[(1.0, 2.0), (-3.0, 5.0)], 20);
        assert_eq!(x, vec![1.0, 5.0]);
    }

    #[test]
    fn ga_is_deterministic_for_a_seed() {
        let cfg = GaConfig {
            generations: 30,
            ..GaConfig::default()
        };
        let f = |x: &[f64]| 1.0 + (x[0] - 0.3).powi(2) + x[1].abs();
        let r1 = minimize(&cfg, &[(-1.0, 1.0), (-1.0, 1.0)], f, None);
        let r2 = minimize(&cfg, &[(-1.0, 1.0), (-1.0, 1.0)], f, None);
        assert_eq!(r1, r2);
        let r3 = minimize(
            &GaConfig { seed: 7, ..cfg },
            &[(-1.0, 1.0), (-1.0, 1.0)],
            f,
            None,
        );
        assert_ne!(r1.best, r3.best);
        // elitism: the best cost never gets worse
        assert!(r1.history.windows(2).all(|w| w[1] <= w[0]));
    }

    #[test]
    fn cond_of_known_matrix() {
        let g = DMatrix::from_row_slice(2, 2, &[4.0, 0.0, 0.0, 1.0]);
        assert!((cond_from_gram(&g) - 2.0).abs() < 1e-12);
        assert!(cond_from_gram(&DMatrix::zeros(2, 2)).is_infinite());
    }
}
