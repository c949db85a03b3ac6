//! Joint axes at the zero pose → modified D-H frames and table rows (see the module docs of
//! [`super`] for the choices).

use std::f64::consts::{FRAC_PI_2, PI};

use nalgebra::Vector3;

use super::geom::Pose;
use super::PARALLEL_TOL;
use crate::dh::JointKind;

/// Below this a distance (m) counts as zero: lines meet, axes coincide.
const LEN_TOL: f64 = 1e-12;

/// A chain joint at the zero pose, in base coordinates.
#[derive(Debug, Clone, Copy)]
pub(crate) struct AxisLine {
    pub kind: JointKind,
    /// A point of the axis (for a prismatic joint: the URDF joint origin).
    pub point: Vector3<f64>,
    /// Unit direction, as the URDF axis points.
    pub dir: Vector3<f64>,
    /// The URDF frame of the link the joint moves.
    pub link: Pose,
}

/// One D-H row at `q = 0` (`theta`/`d` are the offsets of DESIGN.md's table).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Row {
    pub alpha: f64,
    pub a: f64,
    pub theta: f64,
    pub d: f64,
}

/// The D-H frames `F_1..F_n` (base coordinates, zero pose), their rows (row 1 is all zeros:
/// frame 0 is frame 1 at `q_1 = 0`) and the largest mismatch (m or rad) between a row and the
/// frames it was read from (non-zero only for nearly parallel axes).
pub(crate) fn fit(lines: &[AxisLine]) -> (Vec<Pose>, Vec<Row>, f64) {
    let mut frames: Vec<Pose> = Vec::with_capacity(lines.len());
    for (j, line) in lines.iter().enumerate() {
        let z = line.dir;
        let on_axis = |p: Vector3<f64>| line.point + z * (p - line.point).dot(&z);
        let (o, x) = match lines.get(j + 1) {
            Some(next) => {
                let w = z.cross(&next.dir);
                let s2 = w.norm_squared();
                if s2.sqrt() > PARALLEL_TOL {
                    // Foot of the common normal on this axis.
                    let dp = next.point - line.point;
                    let t = (dp.dot(&z) - z.dot(&next.dir) * dp.dot(&next.dir)) / s2;
                    (line.point + z * t, orient(w / s2.sqrt(), &line.link))
                } else {
                    let o = on_axis(line.link.p);
                    let v = (next.point - o) - z * (next.point - o).dot(&z);
                    let dist = v.norm();
                    if dist > LEN_TOL {
                        (o, orient(v / dist, &line.link))
                    } else {
                        (o, free_x(&z, &line.link))
                    }
                }
            }
            None => (on_axis(line.link.p), free_x(&z, &line.link)),
        };
        frames.push(Pose::from_zx(o, z, x));
    }

    let mut rows = Vec::with_capacity(frames.len());
    let mut residual: f64 = 0.0;
    for j in 0..frames.len() {
        if j == 0 {
            rows.push(Row {
                alpha: 0.0,
                a: 0.0,
                theta: 0.0,
                d: 0.0,
            });
            continue;
        }
        let t = frames[j - 1].inverse().then(&frames[j]);
        let alpha = snap_angle((-t.r[(1, 2)]).atan2(t.r[(2, 2)]));
        let theta = snap_angle((-t.r[(0, 1)]).atan2(t.r[(0, 0)]));
        let (sa, ca) = alpha.sin_cos();
        let row = Row {
            alpha,
            a: snap_len(t.p.x),
            theta,
            d: snap_len(-t.p.y * sa + t.p.z * ca),
        };
        let back = Pose::dh(row.alpha, row.a, row.theta, row.d);
        residual = residual
            .max((back.r - t.r).amax())
            .max((back.p - t.p).amax());
        rows.push(row);
    }
    (frames, rows, residual)
}

/// `n` or `-n`: the one closer to the URDF link's x axis (then y, then z when perpendicular).
fn orient(n: Vector3<f64>, link: &Pose) -> Vector3<f64> {
    for reference in [link.x(), link.y(), link.z()] {
        let c = n.dot(&reference);
        if c.abs() > 1e-9 {
            return if c < 0.0 { -n } else { n };
        }
    }
    n
}

/// An x axis where D-H leaves it free: the URDF link's x (else y) axis made normal to `z`.
fn free_x(z: &Vector3<f64>, link: &Pose) -> Vector3<f64> {
    // Of two orthonormal vectors at most one has a component normal to `z` shorter than 1/2.
    let x = link.x();
    let perp = x - z * x.dot(z);
    if perp.norm() >= 0.5 {
        return perp.normalize();
    }
    let y = link.y();
    (y - z * y.dot(z)).normalize()
}

/// Angles within rounding of a multiple of π/2 become exact (for readable tables and the
/// generator's zero propagation); the range is (−π, π].
fn snap_angle(v: f64) -> f64 {
    let k = (v / FRAC_PI_2).round();
    let v = if (v - k * FRAC_PI_2).abs() < 1e-14 {
        match k as i64 {
            0 => 0.0,
            1 => FRAC_PI_2,
            -1 => -FRAC_PI_2,
            _ => PI,
        }
    } else {
        v
    };
    if v <= -PI {
        PI
    } else {
        v
    }
}

fn snap_len(v: f64) -> f64 {
    if v.abs() < 1e-14 {
        0.0
    } else {
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(point: [f64; 3], dir: [f64; 3]) -> AxisLine {
        let dir = Vector3::from(dir).normalize();
        let mut link = Pose::identity();
        link.p = Vector3::from(point);
        AxisLine {
            kind: JointKind::Revolute,
            point: Vector3::from(point),
            dir,
            link,
        }
    }

    /// Re-chains the rows from frame 1 and checks every frame is reproduced.
    fn assert_reproduces(lines: &[AxisLine]) -> Vec<Row> {
        let (frames, rows, residual) = fit(lines);
        assert!(residual < 1e-12, "residual {residual}");
        let mut f = frames[0];
        for (j, r) in rows.iter().enumerate().skip(1) {
            f = f.then(&Pose::dh(r.alpha, r.a, r.theta, r.d));
            assert!((f.r - frames[j].r).amax() < 1e-12 && (f.p - frames[j].p).amax() < 1e-12);
            // z on the URDF axis, through its point, same direction.
            assert!((f.z() - lines[j].dir).amax() < 1e-12);
            assert!((f.p - lines[j].point).cross(&lines[j].dir).amax() < 1e-12);
        }
        rows
    }

    #[test]
    fn planar_arm_along_x_gives_the_textbook_table() {
        let rows = assert_reproduces(&[
            line([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
            line([1.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
        ]);
        assert_eq!(
            rows[1],
            Row {
                alpha: 0.0,
                a: 1.0,
                theta: 0.0,
                d: 0.0
            }
        );
    }

    #[test]
    fn intersecting_skew_parallel_and_collinear_axes() {
        // z then y through the same point (intersecting), then skew, parallel, collinear.
        let rows = assert_reproduces(&[
            line([0.0, 0.0, 0.3], [0.0, 0.0, 1.0]),
            line([0.0, 0.0, 0.3], [0.0, -1.0, 0.0]),
            line([0.2, 0.0, 0.5], [1.0, 0.0, 0.0]),
            line([0.2, 0.1, 0.9], [1.0, 0.0, 0.0]),
            line([0.7, 0.1, 0.9], [1.0, 0.0, 0.0]),
            line([0.7, 0.4, 0.2], [0.3, -0.5, 0.8]),
        ]);
        assert_eq!(rows[1].a, 0.0);
        assert_eq!(rows[1].alpha.abs(), FRAC_PI_2);
    }
}
