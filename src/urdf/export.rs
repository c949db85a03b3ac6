//! D-H arm (+ inertial parameters) → URDF text.
//!
//! Links `link0..linkN` are the D-H frames (so `<inertial>` is the params file's `com` and
//! `inertia_com` unchanged), joint `jointI` is row I as a fixed `<origin>` and `<axis xyz="0 0 1">`.
//! A revolute joint without both position limits becomes `continuous`. When the arm's gravity
//! is not along −z of frame 0, a `world` root link is added, rotated so that it is: importing
//! the file again with the default gravity then gives the arm's gravity direction back (its
//! magnitude too when it is 9.81 m/s²; otherwise pass `--gravity 0,0,-|g|`, as the file's comment
//! says). Viscous and Coulomb friction of the params file's `[effects]` become each joint's
//! `<dynamics damping friction>`; URDF has no place for the other effects.

use nalgebra::{Matrix3, Vector3};
use urdf_rs::{
    Axis, Dynamics, Inertia, Inertial, Joint as UJoint, JointLimit, JointType, Link, LinkName,
    Mass, Pose as UPose, Robot, Vec3,
};

use super::geom::{matrix_to_rpy, Pose};
use crate::dh::{DhTable, JointKind};
use crate::params::InertialParams;

/// The URDF could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error("the parameter file has {found} links but the arm has {expected} joints — give one [[link]] per joint")]
    LinkCount { expected: usize, found: usize },
    #[error("cannot write the URDF: {0}")]
    Serialize(String),
}

/// The URDF of `table`, with the inertial parameters of `params` when given (else massless
/// links).
pub fn export(table: &DhTable, params: Option<&InertialParams>) -> Result<String, ExportError> {
    if let Some(p) = params {
        if p.dof() != table.dof() {
            return Err(ExportError::LinkCount {
                expected: table.dof(),
                found: p.dof(),
            });
        }
    }
    let link = |name: String, inertial: Inertial| Link {
        name,
        inertial,
        visual: Vec::new(),
        collision: Vec::new(),
    };
    let mut links = Vec::new();
    let mut joints = Vec::new();
    let g = Vector3::from(table.gravity);
    if let Some(to_world) = world_rotation(&g) {
        links.push(link("world".into(), Inertial::default()));
        joints.push(joint(
            "world_to_link0".into(),
            JointType::Fixed,
            "world",
            "link0",
            &Pose {
                r: to_world,
                p: Vector3::zeros(),
            },
            JointLimit::default(),
        ));
    }
    links.push(link("link0".into(), Inertial::default()));
    for (i, jt) in table.joints.iter().enumerate() {
        let inertial = params.map_or_else(Inertial::default, |p| {
            let l = &p.links[i];
            let [ixx, ixy, ixz, iyy, iyz, izz] = l.inertia_com;
            Inertial {
                origin: UPose {
                    xyz: Vec3(l.com),
                    rpy: Vec3([0.0; 3]),
                },
                mass: Mass { value: l.m },
                inertia: Inertia {
                    ixx,
                    ixy,
                    ixz,
                    iyy,
                    iyz,
                    izz,
                },
            }
        });
        links.push(link(format!("link{}", i + 1), inertial));
        let origin = Pose::dh(jt.alpha, jt.a, jt.theta, jt.d);
        let (ty, lower, upper) = match (jt.kind, jt.q_min, jt.q_max) {
            (JointKind::Revolute, Some(lo), Some(hi)) => (JointType::Revolute, lo, hi),
            (JointKind::Revolute, _, _) => {
                (JointType::Continuous, f64::NEG_INFINITY, f64::INFINITY)
            }
            (JointKind::Prismatic, lo, hi) => (
                JointType::Prismatic,
                lo.unwrap_or(f64::NEG_INFINITY),
                hi.unwrap_or(f64::INFINITY),
            ),
        };
        let limit = JointLimit {
            lower,
            upper,
            effort: jt.tau_max.unwrap_or(0.0),
            velocity: jt.dq_max.unwrap_or(0.0),
            acceleration: jt.ddq_max.unwrap_or(f64::INFINITY),
            deceleration: jt.ddq_max.unwrap_or(f64::INFINITY),
            jerk: f64::INFINITY,
        };
        let (parent, child) = (format!("link{i}"), format!("link{}", i + 1));
        let mut j = joint(
            format!("joint{}", i + 1),
            ty,
            &parent,
            &child,
            &origin,
            limit,
        );
        j.dynamics = params.and_then(|p| dynamics(p, i));
        joints.push(j);
    }
    let robot = Robot {
        name: table.name.clone(),
        version: None,
        links,
        joints,
        materials: Vec::new(),
    };
    let body =
        urdf_rs::write_to_string(&robot).map_err(|e| ExportError::Serialize(e.to_string()))?;
    let gravity = format!("[{}, {}, {}]", g.x, g.y, g.z);
    let norm = g.norm();
    let hint = if norm == 0.0 || (norm - 9.81).abs() < 1e-12 {
        String::new()
    } else {
        // No "--" inside an XML comment.
        format!(
            " (|g| = {norm} m/s², not 9.81: import with the gravity option 0,0,{})",
            -norm
        )
    };
    Ok(format!(
        "<?xml version=\"1.0\"?>\n<!-- Exported by `dynid export-urdf` from the modified D-H arm `{}`: linkI is D-H frame I,\n     jointI row I. Gravity {gravity} m/s² in frame 0; the root frame has it along -z{hint}. -->\n{body}\n",
        table.name
    ))
}

/// `<dynamics damping friction>` of joint `i`: the viscous and Coulomb coefficients, the effects
/// URDF can carry (none when the parameters have neither).
fn dynamics(p: &InertialParams, i: usize) -> Option<Dynamics> {
    let e = &p.effects;
    let at = |v: &Option<Vec<f64>>| v.as_ref().map(|v| v[i]);
    match (at(&e.viscous), at(&e.coulomb)) {
        (None, None) => None,
        (d, f) => Some(Dynamics {
            damping: d.unwrap_or(0.0),
            friction: f.unwrap_or(0.0),
        }),
    }
}

/// Rotation from frame 0 to a root frame in which `g` points along −z (`None`: already does, or
/// no gravity).
fn world_rotation(g: &Vector3<f64>) -> Option<Matrix3<f64>> {
    let n = g.norm();
    if n == 0.0 {
        return None;
    }
    let u = g / n;
    let down = -Vector3::z();
    if (u - down).amax() < 1e-15 {
        return None;
    }
    // Rows of the rotation: the third is −u (so that R·u = −z), the first any unit vector normal
    // to u. Built directly (not as the shortest rotation) because that loses precision when u is
    // nearly +z, an arm mounted upside down.
    let e = if u.x.abs() <= u.y.abs() && u.x.abs() <= u.z.abs() {
        Vector3::x()
    } else if u.y.abs() <= u.z.abs() {
        Vector3::y()
    } else {
        Vector3::z()
    };
    let first = (e - u * e.dot(&u)).normalize();
    let third = -u;
    let second = third.cross(&first);
    Some(Matrix3::from_rows(&[
        first.transpose(),
        second.transpose(),
        third.transpose(),
    ]))
}

fn joint(
    name: String,
    ty: JointType,
    parent: &str,
    child: &str,
    origin: &Pose,
    limit: JointLimit,
) -> UJoint {
    UJoint {
        name,
        joint_type: ty,
        origin: UPose {
            xyz: Vec3(origin.p.into()),
            rpy: Vec3(matrix_to_rpy(&origin.r)),
        },
        parent: LinkName {
            link: parent.into(),
        },
        child: LinkName { link: child.into() },
        axis: Axis {
            xyz: Vec3([0.0, 0.0, 1.0]),
        },
        limit,
        calibration: None,
        dynamics: None,
        mimic: None,
        safety_controller: None,
    }
}
