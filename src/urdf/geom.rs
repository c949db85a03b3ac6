//! Rigid transforms and URDF roll-pitch-yaw angles (small, allocation-free helpers).

use nalgebra::{Matrix3, Vector3};

/// A rigid transform: `x ↦ r·x + p` (pose of a frame in another: columns of `r` are its axes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Pose {
    pub r: Matrix3<f64>,
    pub p: Vector3<f64>,
}

impl Pose {
    pub fn identity() -> Self {
        Pose {
            r: Matrix3::identity(),
            p: Vector3::zeros(),
        }
    }

    /// A URDF `<origin xyz rpy>`.
    pub fn from_xyz_rpy(xyz: [f64; 3], rpy: [f64; 3]) -> Self {
        Pose {
            r: rpy_to_matrix(rpy),
            p: Vector3::from(xyz),
        }
    }

    /// `self ∘ other`: `other` given in `self`'s frame.
    pub fn then(&self, other: &Pose) -> Pose {
        Pose {
            r: self.r * other.r,
            p: self.r * other.p + self.p,
        }
    }

    pub fn inverse(&self) -> Pose {
        let rt = self.r.transpose();
        Pose {
            r: rt,
            p: -(rt * self.p),
        }
    }

    pub fn x(&self) -> Vector3<f64> {
        self.r.column(0).into_owned()
    }

    pub fn y(&self) -> Vector3<f64> {
        self.r.column(1).into_owned()
    }

    pub fn z(&self) -> Vector3<f64> {
        self.r.column(2).into_owned()
    }

    /// Modified D-H step `RotX(α)·TransX(a)·RotZ(θ)·TransZ(d)`.
    pub fn dh(alpha: f64, a: f64, theta: f64, d: f64) -> Pose {
        let (sa, ca) = alpha.sin_cos();
        let (st, ct) = theta.sin_cos();
        Pose {
            r: Matrix3::new(ct, -st, 0.0, ca * st, ca * ct, -sa, sa * st, sa * ct, ca),
            p: Vector3::new(a, -sa * d, ca * d),
        }
    }

    /// The frame with origin `o`, z axis `z` and x axis `x` (both unit, orthogonal).
    pub fn from_zx(o: Vector3<f64>, z: Vector3<f64>, x: Vector3<f64>) -> Pose {
        let y = z.cross(&x);
        Pose {
            r: Matrix3::from_columns(&[x, y, z]),
            p: o,
        }
    }
}

/// URDF `rpy`: fixed-axis roll about x, then pitch about y, then yaw about z: `Rz(y)·Ry(p)·Rx(r)`.
pub(crate) fn rpy_to_matrix([roll, pitch, yaw]: [f64; 3]) -> Matrix3<f64> {
    let (sr, cr) = roll.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let (sy, cy) = yaw.sin_cos();
    Matrix3::new(
        cy * cp,
        cy * sp * sr - sy * cr,
        cy * sp * cr + sy * sr,
        sy * cp,
        sy * sp * sr + cy * cr,
        sy * sp * cr - cy * sr,
        -sp,
        cp * sr,
        cp * cr,
    )
}

/// Inverse of [`rpy_to_matrix`] for a rotation matrix (yaw = 0 at the pitch = ±π/2 singularity).
/// Near the singularity roll and yaw are ill-conditioned separately, so roll is fitted to what
/// pitch and yaw leave (`Ry(p)ᵀ·Rz(y)ᵀ·R = Rx(r)`): the angles then rebuild `R` to rounding.
pub(crate) fn matrix_to_rpy(r: &Matrix3<f64>) -> [f64; 3] {
    let cp = r[(0, 0)].hypot(r[(1, 0)]);
    let pitch = (-r[(2, 0)]).atan2(cp);
    let yaw = if cp > 1e-12 {
        r[(1, 0)].atan2(r[(0, 0)])
    } else {
        0.0
    };
    let rest = (rpy_to_matrix([0.0, pitch, yaw])).transpose() * r;
    [rest[(2, 1)].atan2(rest[(1, 1)]), pitch, yaw]
}

/// The symmetric tensor of `[ixx, ixy, ixz, iyy, iyz, izz]`.
pub(crate) fn tensor([xx, xy, xz, yy, yz, zz]: [f64; 6]) -> Matrix3<f64> {
    Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz)
}

/// `[ixx, ixy, ixz, iyy, iyz, izz]` of a (symmetrised) tensor.
pub(crate) fn six(m: &Matrix3<f64>) -> [f64; 6] {
    let s = |i: usize, j: usize| 0.5 * (m[(i, j)] + m[(j, i)]);
    [m[(0, 0)], s(0, 1), s(0, 2), m[(1, 1)], s(1, 2), m[(2, 2)]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rpy_round_trips_including_gimbal_lock() {
        for rpy in [
            [0.3, -1.2, 2.9],
            [-3.0, 0.4, -0.2],
            [0.7, std::f64::consts::FRAC_PI_2, 0.0],
        ] {
            let r = rpy_to_matrix(rpy);
            let back = rpy_to_matrix(matrix_to_rpy(&r));
            assert!((r - back).norm() < 1e-12, "{rpy:?}");
        }
    }

    #[test]
    fn dh_step_matches_its_factors() {
        let (alpha, a, theta, d) = (0.4, 0.2, -1.1, 0.3);
        let rx = Pose {
            r: rpy_to_matrix([alpha, 0.0, 0.0]),
            p: Vector3::zeros(),
        };
        let tx = Pose {
            r: Matrix3::identity(),
            p: Vector3::new(a, 0.0, 0.0),
        };
        let rz = Pose {
            r: rpy_to_matrix([0.0, 0.0, theta]),
            p: Vector3::zeros(),
        };
        let tz = Pose {
            r: Matrix3::identity(),
            p: Vector3::new(0.0, 0.0, d),
        };
        let want = rx.then(&tx).then(&rz).then(&tz);
        let got = Pose::dh(alpha, a, theta, d);
        assert!((want.r - got.r).norm() < 1e-15 && (want.p - got.p).norm() < 1e-15);
    }
}
