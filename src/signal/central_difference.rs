//! Central finite differences: first and second derivatives on uniform and uneven grids.

/// First and second derivatives of a uniformly sampled signal: 5-point central differences
/// inside, 3-point one-sided formulas at the two ends.
pub fn central_uniform(x: &[f64], dt: f64) -> (Vec<f64>, Vec<f64>) {
    let n = x.len();
    let mut d1 = vec![0.0; n];
    let mut d2 = vec![0.0; n];
    if n < 5 {
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        return central_uneven(&t, x);
    }
    for k in 2..n - 2 {
        d1[k] = (-x[k + 2] + 8.0 * x[k + 1] - 8.0 * x[k - 1] + x[k - 2]) / (12.0 * dt);
        d2[k] = (-x[k + 2] + 16.0 * x[k + 1] - 30.0 * x[k] + 16.0 * x[k - 1] - x[k - 2])
            / (12.0 * dt * dt);
    }
    for k in [1, n - 2] {
        d1[k] = (x[k + 1] - x[k - 1]) / (2.0 * dt);
        d2[k] = (x[k + 1] - 2.0 * x[k] + x[k - 1]) / (dt * dt);
    }
    d1[0] = (-3.0 * x[0] + 4.0 * x[1] - x[2]) / (2.0 * dt);
    d1[n - 1] = (3.0 * x[n - 1] - 4.0 * x[n - 2] + x[n - 3]) / (2.0 * dt);
    d2[0] = (2.0 * x[0] - 5.0 * x[1] + 4.0 * x[2] - x[3]) / (dt * dt);
    d2[n - 1] = (2.0 * x[n - 1] - 5.0 * x[n - 2] + 4.0 * x[n - 3] - x[n - 4]) / (dt * dt);
    (d1, d2)
}

/// First and second derivatives on an uneven grid: the exact derivatives of the parabola through
/// each three consecutive samples (second-order accurate); one-sided parabolas at the ends.
pub fn central_uneven(t: &[f64], x: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = x.len();
    let mut d1 = vec![0.0; n];
    let mut d2 = vec![0.0; n];
    if n < 3 {
        if n == 2 {
            let s = (x[1] - x[0]) / (t[1] - t[0]);
            d1 = vec![s, s];
        }
        return (d1, d2);
    }
    // Derivatives at `at` of the parabola through (t[i], x[i]) for i = j-1, j, j+1.
    let para = |j: usize, at: f64| -> (f64, f64) {
        let (t0, t1, t2) = (t[j - 1], t[j], t[j + 1]);
        let (x0, x1, x2) = (x[j - 1], x[j], x[j + 1]);
        let l0 = 1.0 / ((t0 - t1) * (t0 - t2));
        let l1 = 1.0 / ((t1 - t0) * (t1 - t2));
        let l2 = 1.0 / ((t2 - t0) * (t2 - t1));
        let d1 = x0 * l0 * ((at - t1) + (at - t2))
            + x1 * l1 * ((at - t0) + (at - t2))
            + x2 * l2 * ((at - t0) + (at - t1));
        let d2 = 2.0 * (x0 * l0 + x1 * l1 + x2 * l2);
        (d1, d2)
    };
    for k in 1..n - 1 {
        (d1[k], d2[k]) = para(k, t[k]);
    }
    (d1[0], d2[0]) = para(1, t[0]);
    (d1[n - 1], d2[n - 1]) = para(n - 2, t[n - 1]);
    (d1, d2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uneven_central_differences_are_exact_on_parabolas() {
        let t = [0.0, 0.1, 0.25, 0.3, 0.5, 0.52];
        let x: Vec<f64> = t.iter().map(|t| 1.0 - 2.0 * t + 4.0 * t * t).collect();
        let (d1, d2) = central_uneven(&t, &x);
        for k in 0..t.len() {
            assert!((d1[k] - (-2.0 + 8.0 * t[k])).abs() < 1e-10);
            assert!((d2[k] - 8.0).abs() < 1e-9);
        }
    }
}
