//! Load-dependent Coulomb friction in the plant: a gear's friction grows with the torque it
//! transmits, `τ = u + μ·sign(q̇)·|u|`, `u` the rigid-body torque plus the additive effects
//! (`|μ| < 1`). Identification fits it as the column [`super::Effect::LoadCoulomb`].

use super::Scales;

/// Joint torque with load-dependent friction `mu`, from `u` (rigid body + other effects).
pub fn load(mu: f64, dq: f64, u: f64, s: &Scales) -> f64 {
    u + mu * s.sign(dq) * u.abs()
}

/// The inverse of [`load`]: the `u` a joint torque `tau` leaves for the rigid body and the other
/// effects, `tau / (1 + μ·s(q̇)·sign(tau))`, `s` the (smoothed) sign (u and tau share their sign
/// for `|μ| < 1`).
pub fn unload(mu: f64, dq: f64, tau: f64, s: &Scales) -> f64 {
    tau / (1.0 + mu * s.sign(dq) * super::sign(tau))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unload_inverts_load_for_both_signs() {
        for &(mu, dq, u) in &[
            (0.3, 1.0, 2.0),
            (0.3, -1.0, 2.0),
            (0.2, 0.5, -3.0),
            (0.1, 0.0, 1.5),
        ] {
            for s in [Scales::EXACT, Scales::from_rms_velocity(1.0)] {
                let tau = load(mu, dq, u, &s);
                assert!((unload(mu, dq, tau, &s) - u).abs() < 1e-15 * u.abs());
            }
        }
    }
}
