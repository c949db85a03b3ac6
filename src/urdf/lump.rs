//! Rigid bodies welded together: exact total mass, centre of mass and inertia.

use nalgebra::{Matrix3, Vector3};

/// One body in a common frame: mass, centre of mass, inertia tensor about the centre of mass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Body {
    pub m: f64,
    pub com: Vector3<f64>,
    pub inertia: Matrix3<f64>,
}

impl Body {
    pub fn is_empty(&self) -> bool {
        self.m == 0.0 && self.inertia == Matrix3::zeros()
    }
}

/// `m·(|c|²·1 − c·cᵀ)`: the parallel-axis term for a point mass `m` at `c`.
fn steiner(m: f64, c: &Vector3<f64>) -> Matrix3<f64> {
    m * (Matrix3::identity() * c.norm_squared() - c * c.transpose())
}

/// The single body equivalent to `bodies` rigidly joined (all given in the same frame).
/// Two passes — centre of mass first, then inertias about it — so that no large parallel-axis
/// terms are added and subtracted again. A massless set keeps the sum of its (rotational)
/// inertias and a zero centre of mass.
pub(crate) fn lump(bodies: &[Body]) -> Body {
    let m: f64 = bodies.iter().map(|b| b.m).sum();
    let com = if m > 0.0 {
        bodies.iter().map(|b| b.com * b.m).sum::<Vector3<f64>>() / m
    } else {
        Vector3::zeros()
    };
    let inertia = bodies
        .iter()
        .map(|b| b.inertia + steiner(b.m, &(b.com - com)))
        .sum();
    Body { m, com, inertia }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_point_masses_make_a_dumbbell() {
        let a = Body {
            m: 1.0,
            com: Vector3::new(-1.0, 0.0, 0.0),
            inertia: Matrix3::zeros(),
        };
        let b = Body {
            m: 3.0,
            com: Vector3::new(1.0, 0.0, 0.0),
            inertia: Matrix3::identity() * 0.1,
        };
        let s = lump(&[a, b]);
        assert_eq!(s.m, 4.0);
        assert!((s.com - Vector3::new(0.5, 0.0, 0.0)).norm() < 1e-15);
        // About the COM: 1·1.5² + 3·0.5² = 3 about y and z, plus b's own 0.1.
        assert!((s.inertia[(1, 1)] - 3.1).abs() < 1e-14 && (s.inertia[(2, 2)] - 3.1).abs() < 1e-14);
        assert!((s.inertia[(0, 0)] - 0.1).abs() < 1e-15);
    }

    #[test]
    fn lumping_is_associative() {
        let b = |m: f64, x: f64, i: f64| Body {
            m,
            com: Vector3::new(x, 0.2 * x, -x),
            inertia: Matrix3::identity() * i,
        };
        let (p, q, r) = (b(1.0, 0.3, 0.01), b(2.0, -0.4, 0.02), b(0.5, 1.1, 0.003));
        let all = lump(&[p, q, r]);
        let nested = lump(&[lump(&[p, q]), r]);
        assert!(
            (all.inertia - nested.inertia).amax() < 1e-14 && (all.com - nested.com).amax() < 1e-15
        );
    }
}
