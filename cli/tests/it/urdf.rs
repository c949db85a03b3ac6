//! URDF import/export. The oracles: (1) a URDF-native recursive Newton–Euler written here from
//! the URDF semantics (world-frame, joints as URDF defines them, bodies never lumped) on random
//! trees with every geometry and joint kind; (2) the round trip arm → URDF → arm; (3) Pinocchio
//! on real robots (`tests/pinocchio/check_urdf.py`, with the Pinocchio and example-robot-data
//! that scripts/test.sh installs into `.venv/`; without them the test fails and says so).

use std::f64::consts::{FRAC_PI_2, PI};
use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

use dynid::dh::{DhTable, JointKind};
use dynid::params::{InertialParams, ParamsOptions};
use dynid::reference::RefModel;
use dynid::urdf::{export, import_str, ImportOptions, UrdfErrorKind};
use nalgebra::{Matrix3, Vector3};
use rand::Rng;

use crate::common::*;

// ---------------------------------------------------------------------------------------------
// A URDF-native oracle.

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Revolute,
    Continuous,
    Prismatic,
    Fixed,
}

#[derive(Debug, Clone)]
struct TJoint {
    kind: Kind,
    parent: usize,
    xyz: [f64; 3],
    rpy: [f64; 3],
    axis: [f64; 3],
    /// Index into the chain (the D-H joints), `None` for fixed and locked joints.
    chain: Option<usize>,
}

/// `(mass, com xyz, inertial rpy, inertia [ixx ixy ixz iyy iyz izz])`.
type TInertial = (f64, [f64; 3], [f64; 3], [f64; 6]);

#[derive(Debug, Clone)]
struct TLink {
    /// `None`: no `<inertial>`.
    inertial: Option<TInertial>,
}

/// Link 0 is the root; link `i ≥ 1` hangs from `joints[i - 1]`.
#[derive(Debug, Clone)]
pub(super) struct TRobot {
    links: Vec<TLink>,
    joints: Vec<TJoint>,
}

fn rot(rpy: [f64; 3]) -> Matrix3<f64> {
    let [r, p, y] = rpy;
    let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, r.cos(), -r.sin(), 0.0, r.sin(), r.cos());
    let ry = Matrix3::new(p.cos(), 0.0, p.sin(), 0.0, 1.0, 0.0, -p.sin(), 0.0, p.cos());
    let rz = Matrix3::new(y.cos(), -y.sin(), 0.0, y.sin(), y.cos(), 0.0, 0.0, 0.0, 1.0);
    rz * ry * rx
}

fn axis_angle(axis: &Vector3<f64>, q: f64) -> Matrix3<f64> {
    nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(*axis), q).into_inner()
}

fn f(v: f64) -> String {
    format!("{v:?}")
}

impl TRobot {
    pub(super) fn urdf(&self) -> String {
        let mut s = String::from("<?xml version=\"1.0\"?>\n<robot name=\"random\">\n");
        for (i, l) in self.links.iter().enumerate() {
            match l.inertial {
                None => writeln!(s, "  <link name=\"l{i}\"/>").unwrap(),
                Some((m, c, rpy, [xx, xy, xz, yy, yz, zz])) => writeln!(
                    s,
                    "  <link name=\"l{i}\"><inertial><origin xyz=\"{} {} {}\" rpy=\"{} {} {}\"/><mass value=\"{}\"/>\
                     <inertia ixx=\"{}\" ixy=\"{}\" ixz=\"{}\" iyy=\"{}\" iyz=\"{}\" izz=\"{}\"/></inertial></link>",
                    f(c[0]), f(c[1]), f(c[2]), f(rpy[0]), f(rpy[1]), f(rpy[2]), f(m),
                    f(xx), f(xy), f(xz), f(yy), f(yz), f(zz)
                )
                .unwrap(),
            }
        }
        for (k, j) in self.joints.iter().enumerate() {
            let ty = match j.kind {
                Kind::Revolute => "revolute",
                Kind::Continuous => "continuous",
                Kind::Prismatic => "prismatic",
                Kind::Fixed => "fixed",
            };
            writeln!(
                s,
                "  <joint name=\"j{}\" type=\"{ty}\"><parent link=\"l{}\"/><child link=\"l{}\"/>\
                 <origin xyz=\"{} {} {}\" rpy=\"{} {} {}\"/><axis xyz=\"{} {} {}\"/>\
                 <limit lower=\"-3\" upper=\"3\" effort=\"10\" velocity=\"2\"/></joint>",
                k + 1,
                j.parent,
                k + 1,
                f(j.xyz[0]),
                f(j.xyz[1]),
                f(j.xyz[2]),
                f(j.rpy[0]),
                f(j.rpy[1]),
                f(j.rpy[2]),
                f(j.axis[0]),
                f(j.axis[1]),
                f(j.axis[2])
            )
            .unwrap();
        }
        s + "</robot>\n"
    }

    /// Torques of the chain joints by Newton–Euler in world coordinates: every URDF body on its
    /// own, joints off the chain held at 0, gravity `g` in the root frame.
    fn torques(&self, q: &[f64], dq: &[f64], ddq: &[f64], g: Vector3<f64>) -> Vec<f64> {
        let n = self.links.len();
        let mut rw = vec![Matrix3::identity(); n];
        let mut o = vec![Vector3::zeros(); n];
        let mut w = vec![Vector3::zeros(); n];
        let mut dw = vec![Vector3::zeros(); n];
        let mut a = vec![-g; n]; // acceleration of each link origin; the root's is -g
        let mut s = vec![Vector3::zeros(); n];
        for (k, j) in self.joints.iter().enumerate() {
            let (l, p) = (k + 1, j.parent);
            let r0 = rw[p] * rot(j.rpy);
            let axis = Vector3::from(j.axis).normalize();
            let (qi, dqi, ddqi) = j.chain.map_or((0.0, 0.0, 0.0), |c| (q[c], dq[c], ddq[c]));
            s[l] = r0 * axis;
            let base = o[p] + rw[p] * Vector3::from(j.xyz);
            let (r, ap, wp, dwp) = (o[p], a[p], w[p], dw[p]);
            let lever = |x: Vector3<f64>| ap + dwp.cross(&(x - r)) + wp.cross(&wp.cross(&(x - r)));
            match j.kind {
                Kind::Prismatic => {
                    rw[l] = r0;
                    o[l] = base + s[l] * qi;
                    w[l] = wp;
                    dw[l] = dwp;
                    a[l] = lever(o[l]) + 2.0 * wp.cross(&(s[l] * dqi)) + s[l] * ddqi;
                }
                _ => {
                    rw[l] = r0 * axis_angle(&axis, qi);
                    o[l] = base;
                    w[l] = wp + s[l] * dqi;
                    dw[l] = dwp + wp.cross(&(s[l] * dqi)) + s[l] * ddqi;
                    a[l] = lever(o[l]);
                }
            }
        }
        // Backward: force and moment (about the link origin) each joint transmits.
        let mut force = vec![Vector3::zeros(); n];
        let mut moment = vec![Vector3::zeros(); n];
        for l in (1..n).rev() {
            if let Some((m, c, rpy, i6)) = self.links[l].inertial {
                let c = o[l] + rw[l] * Vector3::from(c);
                let ri = rw[l] * rot(rpy);
                let [xx, xy, xz, yy, yz, zz] = i6;
                let iw = ri * Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz) * ri.transpose();
                let ac = a[l] + dw[l].cross(&(c - o[l])) + w[l].cross(&w[l].cross(&(c - o[l])));
                let fl = m * ac;
                force[l] += fl;
                moment[l] += iw * dw[l] + w[l].cross(&(iw * w[l])) + (c - o[l]).cross(&fl);
            }
            let p = self.joints[l - 1].parent;
            if p > 0 {
                let (fl, ml) = (force[l], moment[l]);
                force[p] += fl;
                moment[p] += ml + (o[l] - o[p]).cross(&fl);
            }
        }
        let dof = self.joints.iter().filter(|j| j.chain.is_some()).count();
        let mut tau = vec![0.0; dof];
        for (k, j) in self.joints.iter().enumerate() {
            if let Some(c) = j.chain {
                let l = k + 1;
                tau[c] = if j.kind == Kind::Prismatic {
                    s[l].dot(&force[l])
                } else {
                    s[l].dot(&moment[l])
                };
            }
        }
        tau
    }
}

/// A random rigid body: mass, COM, a rotated inertial frame and principal moments that satisfy
/// the triangle inequality.
fn random_inertial(rng: &mut impl Rng) -> TInertial {
    let m = rng.gen_range(0.1..3.0);
    let c = [
        rng.gen_range(-0.3..0.3),
        rng.gen_range(-0.3..0.3),
        rng.gen_range(-0.3..0.3),
    ];
    let rpy = [
        rng.gen_range(-PI..PI),
        rng.gen_range(-1.5..1.5),
        rng.gen_range(-PI..PI),
    ];
    // Principal moments from a box's semi-axes: always physical.
    let (x, y, z): (f64, f64, f64) = (
        rng.gen_range(0.02..0.3),
        rng.gen_range(0.02..0.3),
        rng.gen_range(0.02..0.3),
    );
    let k = m / 5.0;
    let d = Matrix3::from_diagonal(&Vector3::new(
        k * (y * y + z * z),
        k * (x * x + z * z),
        k * (x * x + y * y),
    ));
    let r = rot([
        rng.gen_range(-PI..PI),
        rng.gen_range(-1.5..1.5),
        rng.gen_range(-PI..PI),
    ]);
    let i = r * d * r.transpose();
    (
        m,
        c,
        rpy,
        [
            i[(0, 0)],
            i[(0, 1)],
            i[(0, 2)],
            i[(1, 1)],
            i[(1, 2)],
            i[(2, 2)],
        ],
    )
}

/// A random tree: a chain of `dof` movable joints with fixed links between some of them, a
/// locked branch (revolute joint + body) on a middle link, a body fixed to the base; axes along
/// ±x/±y/±z or unaligned, frames aligned (so axes are often parallel or intersecting) or not.
pub(super) fn random_robot(rng: &mut impl Rng, dof: usize) -> TRobot {
    let mut links = vec![TLink {
        inertial: Some(random_inertial(rng)),
    }];
    let mut joints = Vec::new();
    let add = |links: &mut Vec<TLink>, joints: &mut Vec<TJoint>, j: TJoint, inertial| {
        joints.push(j);
        links.push(TLink { inertial });
        links.len() - 1
    };
    let origin = |rng: &mut dyn rand::RngCore| -> ([f64; 3], [f64; 3]) {
        let aligned = rng.gen_bool(0.6);
        let mut xyz = [0.0; 3];
        for v in &mut xyz {
            *v = if aligned && rng.gen_bool(0.5) {
                0.0
            } else {
                rng.gen_range(-0.4..0.4)
            };
        }
        let rpy = if aligned {
            [0, 1, 2].map(|_| FRAC_PI_2 * f64::from(rng.gen_range(-2i32..=2)))
        } else {
            [
                rng.gen_range(-PI..PI),
                rng.gen_range(-1.5..1.5),
                rng.gen_range(-PI..PI),
            ]
        };
        (xyz, rpy)
    };
    // A body fixed to the base: must not matter.
    let (xyz, rpy) = origin(rng);
    let fixed = TJoint {
        kind: Kind::Fixed,
        parent: 0,
        xyz,
        rpy,
        axis: [1.0, 0.0, 0.0],
        chain: None,
    };
    let inertial = Some(random_inertial(rng));
    add(&mut links, &mut joints, fixed, inertial);

    let mut parent = 0;
    for c in 0..dof {
        let kind = match rng.gen_range(0..10) {
            0..=1 => Kind::Prismatic,
            2..=3 => Kind::Continuous,
            _ => Kind::Revolute,
        };
        let axis = match rng.gen_range(0..6) {
            0 => [0.0, 0.0, 1.0],
            1 => [0.0, -1.0, 0.0],
            2 => [1.0, 0.0, 0.0],
            3 => [0.0, 1.0, -1.0], // not unit: URDF normalises
            _ => [
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(0.2..1.0),
            ],
        };
        let (xyz, rpy) = origin(rng);
        let inertial = if rng.gen_bool(0.85) {
            Some(random_inertial(rng))
        } else {
            None
        };
        let j = TJoint {
            kind,
            parent,
            xyz,
            rpy,
            axis,
            chain: Some(c),
        };
        parent = add(&mut links, &mut joints, j, inertial);
        if rng.gen_bool(0.4) {
            let (xyz, rpy) = origin(rng);
            let fixed = TJoint {
                kind: Kind::Fixed,
                parent,
                xyz,
                rpy,
                axis: [1.0, 0.0, 0.0],
                chain: None,
            };
            let inertial = Some(random_inertial(rng));
            let l = add(&mut links, &mut joints, fixed, inertial);
            // Continue the chain from the fixed link sometimes, else it is a side body.
            if rng.gen_bool(0.5) {
                parent = l;
            }
        }
        if c == dof / 2 {
            // A locked branch: a revolute joint off the chain carrying a body.
            let (xyz, rpy) = origin(rng);
            let j = TJoint {
                kind: Kind::Revolute,
                parent,
                xyz,
                rpy,
                axis: [0.0, 1.0, 0.0],
                chain: None,
            };
            let inertial = Some(random_inertial(rng));
            add(&mut links, &mut joints, j, inertial);
        }
    }
    // A massive tool fixed at the tip.
    let (xyz, rpy) = origin(rng);
    let tool = TJoint {
        kind: Kind::Fixed,
        parent,
        xyz,
        rpy,
        axis: [1.0, 0.0, 0.0],
        chain: None,
    };
    let inertial = Some(random_inertial(rng));
    add(&mut links, &mut joints, tool, inertial);
    TRobot { links, joints }
}

pub(super) fn tip_of(robot: &TRobot) -> String {
    let last = robot
        .joints
        .iter()
        .rposition(|j| j.chain.is_some())
        .expect("a chain joint");
    format!("l{}", last + 1)
}

pub(super) fn reference_torques(
    table: &DhTable,
    p: &[f64],
    q: &[f64],
    dq: &[f64],
    ddq: &[f64],
) -> Vec<f64> {
    let model = RefModel::new(table);
    let mut ws = model.workspace();
    let mut tau = vec![0.0; table.dof()];
    model.inverse_dynamics(&mut ws, q, dq, ddq, p, &mut tau);
    tau
}

#[test]
fn imported_tables_reproduce_a_urdf_newton_euler_on_random_trees() {
    let mut rng = rng(8);
    for case in 0..40 {
        let dof = 1 + case % 7;
        let robot = random_robot(&mut rng, dof);
        let urdf = robot.urdf();
        let g = Vector3::new(rng.gen_range(-3.0..3.0), rng.gen_range(-3.0..3.0), -9.81);
        let opts = ImportOptions {
            tip: Some(tip_of(&robot)),
            gravity: Some(g.into()),
            ..Default::default()
        };
        let arm = import_str(&urdf, "random.urdf", &opts)
            .unwrap_or_else(|e| panic!("case {case}: {e}\n{urdf}"));
        assert_eq!(arm.table.dof(), dof);
        for (j, row) in arm.table.joints.iter().enumerate() {
            let want = if robot
                .joints
                .iter()
                .any(|t| t.chain == Some(j) && t.kind == Kind::Prismatic)
            {
                JointKind::Prismatic
            } else {
                JointKind::Revolute
            };
            assert_eq!(row.kind, want, "case {case} joint {j}");
        }
        let p = arm.params.full_vector();
        for _ in 0..5 {
            let (q, dq, ddq) = random_state(&mut rng, dof);
            let want = robot.torques(&q, &dq, &ddq, g);
            let got = reference_torques(&arm.table, &p, &q, &dq, &ddq);
            assert_close(
                &got,
                &want,
                1e-10,
                &format!("case {case} ({dof} joints) τ\n{urdf}\n{}", arm.dh_toml),
            );
        }
    }
}

#[test]
fn zero_pose_and_positive_motion_are_the_urdfs() {
    // A pendulum along -y: with the default gravity, q > 0 about -y lifts the bob toward +x...
    let urdf = r#"<robot name="p"><link name="base"/>
      <link name="arm"><inertial><origin xyz="0 0 -1"/><mass value="1"/>
        <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
      <joint name="j" type="continuous"><parent link="base"/><child link="arm"/>
        <origin xyz="0.3 0.2 1.5" rpy="0.1 0.2 0.3"/><axis xyz="0 -1 0"/></joint></robot>"#;
    let arm = import_str(urdf, "p.urdf", &ImportOptions::default()).unwrap();
    let p = arm.params.full_vector();
    let tau = |q: f64| reference_torques(&arm.table, &p, &[q], &[0.0], &[0.0])[0];
    // Oracle: the URDF pendulum by hand, through the same frames.
    let robot = TRobot {
        links: vec![
            TLink { inertial: None },
            TLink {
                inertial: Some((1.0, [0.0, 0.0, -1.0], [0.0; 3], [0.0; 6])),
            },
        ],
        joints: vec![TJoint {
            kind: Kind::Continuous,
            parent: 0,
            xyz: [0.3, 0.2, 1.5],
            rpy: [0.1, 0.2, 0.3],
            axis: [0.0, -1.0, 0.0],
            chain: Some(0),
        }],
    };
    for q in [0.0, 0.4, -1.1] {
        let want = robot.torques(&[q], &[0.0], &[0.0], Vector3::new(0.0, 0.0, -9.81))[0];
        assert!(
            (tau(q) - want).abs() < 1e-12,
            "q = {q}: {} vs {want}",
            tau(q)
        );
    }
    assert!(tau(0.4).abs() > 1.0, "gravity acts away from the zero pose");
}

#[test]
fn nearly_parallel_axes_are_treated_as_parallel_with_a_warning() {
    // Axis 2 tilted by 3e-9 rad from axis 1 toward the link (about y, which no D-H twist can
    // express): the exact common normal would run 1e8 m away.
    let inertial = Some(random_inertial(&mut rng(5)));
    let joint = |parent, xyz, rpy| TJoint {
        kind: Kind::Revolute,
        parent,
        xyz,
        rpy,
        axis: [0.0, 0.0, 1.0],
        chain: Some(parent),
    };
    let robot = TRobot {
        links: vec![
            TLink { inertial: None },
            TLink { inertial },
            TLink { inertial },
        ],
        joints: vec![
            joint(0, [0.0, 0.0, 0.3], [0.0; 3]),
            joint(1, [0.5, 0.0, 0.0], [0.0, 3e-9, 0.0]),
        ],
    };
    let arm = import_str(&robot.urdf(), "tilt.urdf", &ImportOptions::default()).unwrap();
    assert!(
        arm.warnings
            .iter()
            .any(|w| w.contains("parallel to within")),
        "{:?}",
        arm.warnings
    );
    assert_eq!(arm.table.joints[1].a, 0.5);
    let p = arm.params.full_vector();
    let mut rng = rng(6);
    for _ in 0..5 {
        let (q, dq, ddq) = random_state(&mut rng, 2);
        let want = robot.torques(&q, &dq, &ddq, Vector3::new(0.0, 0.0, -9.81));
        // The error is of the order of the neglected tilt.
        assert_close(
            &reference_torques(&arm.table, &p, &q, &dq, &ddq),
            &want,
            1e-8,
            "τ",
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Round trip.

/// Random physical parameters as a params file (inertia about the origin from point clouds).
fn params_toml(rng: &mut impl Rng, dof: usize) -> String {
    let p = cloud_params(&random_clouds(rng, dof));
    let mut s = String::new();
    for l in p.chunks(10) {
        let m = l[9];
        writeln!(
            s,
            "[[link]]\nm = {m:?}\ncom = [{:?}, {:?}, {:?}]",
            l[6] / m,
            l[7] / m,
            l[8] / m
        )
        .unwrap();
        writeln!(
            s,
            "inertia_origin = [{:?}, {:?}, {:?}, {:?}, {:?}, {:?}]\n",
            l[0], l[1], l[2], l[3], l[4], l[5]
        )
        .unwrap();
    }
    s
}

#[test]
fn every_arm_survives_export_then_import() {
    let mut rng = rng(3);
    for table in all_tables() {
        let dof = table.dof();
        let params = InertialParams::from_str(
            &params_toml(&mut rng, dof),
            "p.toml",
            dof,
            &ParamsOptions::default(),
        )
        .unwrap_or_else(|e| panic!("{e}"));
        let urdf = export(&table, Some(&params)).unwrap_or_else(|e| panic!("{}: {e}", table.name));
        // The exported root frame has gravity along -z; only its magnitude needs saying.
        let g = Vector3::from(table.gravity).norm();
        let opts = ImportOptions {
            gravity: Some([0.0, 0.0, -g]),
            ..Default::default()
        };
        let back = import_str(&urdf, &format!("{}.urdf", table.name), &opts)
            .unwrap_or_else(|e| panic!("{}: {e}\n{urdf}", table.name));
        assert_eq!(back.table.name, table.name);
        assert_eq!(back.table.dof(), dof);
        // Frames 1..n are the exported links, so rows 2..n and the parameters come back as they
        // were (frame 0 is frame 1's zero pose, so row 1 is zero and gravity turns with it).
        for (j, (a, b)) in table
            .joints
            .iter()
            .zip(&back.table.joints)
            .enumerate()
            .skip(1)
        {
            let (x, y) = ([a.alpha, a.a, a.d, a.theta], [b.alpha, b.a, b.d, b.theta]);
            assert_close(&y, &x, 1e-12, &format!("{} row {}", table.name, j + 1));
            assert_eq!(a.kind, b.kind);
        }
        let (p, p_back) = (params.full_vector(), back.params.full_vector());
        assert_close(&p_back, &p, 1e-12, &format!("{} parameters", table.name));
        for _ in 0..10 {
            let (q, dq, ddq) = random_state(&mut rng, dof);
            let want = reference_torques(&table, &p, &q, &dq, &ddq);
            let got = reference_torques(&back.table, &p_back, &q, &dq, &ddq);
            assert_close(
                &got,
                &want,
                1e-12,
                &format!("{} τ after the round trip", table.name),
            );
        }
    }
}

#[test]
fn joint_limits_survive_the_round_trip() {
    let table = DhTable::from_path(
        &Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("arms/puma560.toml"),
    )
    .unwrap();
    let urdf = export(&table, None).unwrap();
    let back = import_str(&urdf, "puma560.urdf", &ImportOptions::default()).unwrap();
    for (a, b) in table.joints.iter().zip(&back.table.joints) {
        assert_eq!(
            (a.q_min, a.q_max, a.dq_max, a.tau_max),
            (b.q_min, b.q_max, b.dq_max, b.tau_max)
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Chain selection, lumping, notes.

const LINK: &str = r#"<inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>"#;

/// A URDF from `(name, type, parent, child, extra)` joints; every named link gets [`LINK`].
fn urdf_of(joints: &[(&str, &str, &str, &str, &str)]) -> String {
    let mut links: Vec<&str> = Vec::new();
    for &(_, _, p, c, _) in joints {
        for l in [p, c] {
            if !links.contains(&l) {
                links.push(l);
            }
        }
    }
    let mut s = String::from("<robot name=\"t\">\n");
    for l in links {
        writeln!(s, "<link name=\"{l}\">{LINK}</link>").unwrap();
    }
    for (name, ty, p, c, extra) in joints {
        writeln!(
            s,
            "<joint name=\"{name}\" type=\"{ty}\"><parent link=\"{p}\"/><child link=\"{c}\"/><origin xyz=\"0 0 0.2\"/><axis xyz=\"0 1 0\"/>{extra}</joint>"
        )
        .unwrap();
    }
    s + "</robot>"
}

fn import(
    text: &str,
    opts: &ImportOptions,
) -> Result<dynid::urdf::Imported, dynid::urdf::UrdfError> {
    import_str(text, "t.urdf", opts)
}

/// A hand with two mimic fingers at the tip of a 2-joint arm, and a camera on the base.
pub(super) fn arm_with_gripper() -> String {
    urdf_of(&[
        ("j1", "revolute", "base", "l1", ""),
        ("j2", "revolute", "l1", "l2", ""),
        ("flange", "fixed", "l2", "hand", ""),
        ("f1", "prismatic", "hand", "left", ""),
        ("f2", "prismatic", "hand", "right", r#"<mimic joint="f1"/>"#),
        ("cam", "revolute", "base", "camera", ""),
    ])
}

#[test]
fn the_default_chain_skips_mimic_grippers_and_lumps_them() {
    let arm = import(&arm_with_gripper(), &ImportOptions::default()).unwrap();
    assert_eq!(arm.chain, ["j1", "j2"]);
    // Link 2 carries l2, hand and both fingers: 4 kg.
    assert_eq!(arm.params.links[1].m, 4.0);
    assert_eq!(arm.params.links[0].m, 1.0);
    let notes = arm.notes.join("\n");
    assert!(
        notes.contains("f1 → link 2") && notes.contains("f2 → link 2"),
        "{notes}"
    );
    assert!(
        notes.contains("cam"),
        "the camera joint on the base is mentioned: {notes}"
    );
    assert!(notes.contains("base `base` is fixed"), "{notes}");
    assert!(
        arm.params_toml
            .contains("# link 2 carries hand, left, right"),
        "{}",
        arm.params_toml
    );
}

#[test]
fn base_and_tip_choose_a_sub_chain() {
    let opts = ImportOptions {
        base: Some("l1".into()),
        tip: Some("hand".into()),
        ..Default::default()
    };
    let arm = import(&arm_with_gripper(), &opts).unwrap();
    assert_eq!(arm.chain, ["j2"]);
    let err = import(
        &arm_with_gripper(),
        &ImportOptions {
            tip: Some("left".into()),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(matches!(err.kind, UrdfErrorKind::Mimic { .. }), "{err}");
    assert!(err.to_string().contains("`f2` mimics `f1`"), "{err}");
    let err = import(
        &arm_with_gripper(),
        &ImportOptions {
            base: Some("l2".into()),
            tip: Some("l1".into()),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(
        matches!(err.kind, UrdfErrorKind::TipNotBelowBase { .. }),
        "{err}"
    );
    let err = import(
        &arm_with_gripper(),
        &ImportOptions {
            tip: Some("hnad".into()),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(err.to_string().contains("did you mean `hand`?"), "{err}");
}

#[test]
fn two_equally_long_chains_must_be_chosen_between() {
    let urdf = urdf_of(&[
        ("a1", "revolute", "torso", "la1", ""),
        ("a2", "revolute", "la1", "la2", ""),
        ("b1", "revolute", "torso", "lb1", ""),
        ("b2", "continuous", "lb1", "lb2", ""),
    ]);
    let err = import(&urdf, &ImportOptions::default()).unwrap_err();
    assert!(
        matches!(&err.kind, UrdfErrorKind::AmbiguousChain { joints: 2, tips } if tips == &["la2", "lb2"]),
        "{err}"
    );
    assert!(err.to_string().contains("--tip"), "{err}");
    let arm = import(
        &urdf,
        &ImportOptions {
            tip: Some("lb2".into()),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(arm.chain, ["b1", "b2"]);
    assert!(
        arm.table.joints[1].q_min.is_none(),
        "continuous joints have no position limits"
    );
}

#[test]
fn names_default_to_the_file_stem_as_an_identifier() {
    let urdf = urdf_of(&[("j", "revolute", "a", "b", "")]);
    let arm = import_str(&urdf, "/x/2dof-Planar.urdf", &ImportOptions::default()).unwrap();
    assert_eq!(arm.table.name, "arm_2dof_planar");
    let err = import(
        &urdf,
        &ImportOptions {
            name: Some("My Arm".into()),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(matches!(err.kind, UrdfErrorKind::BadName { .. }), "{err}");
}

// ---------------------------------------------------------------------------------------------
// Refusals and warnings name the file and the element.

fn refused(text: &str) -> String {
    let err = import(text, &ImportOptions::default()).unwrap_err();
    let msg = err.to_string();
    assert!(msg.starts_with("t.urdf: "), "{msg}");
    msg
}

#[test]
fn unsupported_structures_are_refused_with_the_element_named() {
    let m = refused(&urdf_of(&[
        ("j1", "revolute", "a", "b", ""),
        ("j2", "ball", "b", "c", ""),
    ]));
    assert!(
        m.contains("<joint name=\"j2\">: unknown type `ball`"),
        "{m}"
    );
    let m = refused(&urdf_of(&[
        ("free", "floating", "world", "a", ""),
        ("j1", "revolute", "a", "b", ""),
    ]));
    assert!(
        m.contains("type=\"floating\"> is on the chain") && m.contains("--base"),
        "{m}"
    );
    let m = refused(&urdf_of(&[("j1", "planar", "a", "b", "")]));
    assert!(m.contains("type=\"planar\">"), "{m}");
    let m = refused(&urdf_of(&[
        ("j1", "revolute", "a", "b", ""),
        ("j2", "revolute", "a", "c", ""),
        ("j3", "revolute", "b", "c", ""),
    ]));
    assert!(
        m.contains("<link name=\"c\"> is the child of 2 joints (j2, j3): a closed loop"),
        "{m}"
    );
    let m = refused(&urdf_of(&[
        ("j1", "revolute", "a", "b", ""),
        ("j2", "revolute", "c", "d", ""),
    ]));
    assert!(m.contains("2 root links (a, c)"), "{m}");
    let m = refused(&urdf_of(&[
        ("j1", "revolute", "a", "b", ""),
        ("j2", "revolute", "b", "a", ""),
    ]));
    assert!(m.contains("loop"), "{m}");
    let m = refused(&urdf_of(&[("j1", "fixed", "a", "b", "")]));
    assert!(m.contains("no movable joint"), "{m}");
    let m = refused(&urdf_of(&[(
        "j1",
        "revolute",
        "a",
        "b",
        r#"<mimic joint="j0"/>"#,
    )]));
    assert!(m.contains("mimic"), "{m}");
    let missing = r#"<robot name="t"><link name="a"/><joint name="j" type="revolute"><parent link="a"/><child link="nowhere"/></joint></robot>"#;
    let m = refused(missing);
    assert!(
        m.contains("<joint name=\"j\">: <child link=\"nowhere\"> names no <link>"),
        "{m}"
    );
    let m = refused(r#"<robot name="t"><link name="a"/><link name="a"/></robot>"#);
    assert!(m.contains("two <link> elements are named `a`"), "{m}");
    let m = refused("<robot name=\"t\"><link name=\"a\"></robot>");
    assert!(m.contains("not a valid URDF"), "{m}");
    let m = refused(
        r#"<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="t"><xacro:property name="x" value="1"/></robot>"#,
    );
    assert!(m.contains("xacro"), "{m}");
    let zero_axis = urdf_of(&[("j1", "revolute", "a", "b", "")])
        .replace("<axis xyz=\"0 1 0\"/>", "<axis xyz=\"0 0 0\"/>");
    assert!(refused(&zero_axis).contains("<joint name=\"j1\">: <axis xyz=\"0 0 0\">"));
    let nan = urdf_of(&[("j1", "revolute", "a", "b", "")])
        .replace("xyz=\"0 0 0.2\"", "xyz=\"0 nan 0.2\"");
    assert!(refused(&nan).contains("<joint name=\"j1\">: <origin> is not a finite number"));
    let negative = urdf_of(&[("j1", "revolute", "a", "b", "")]).replacen(
        "<mass value=\"1\"/>",
        "<mass value=\"-1\"/>",
        2,
    );
    assert!(refused(&negative)
        .contains("<link name=\"b\"> <inertial> <mass value=\"-1\">: masses must be ≥ 0 kg"));
    let chain: Vec<(String, String, String)> = (0..13)
        .map(|i| (format!("j{i}"), format!("l{i}"), format!("l{}", i + 1)))
        .collect();
    let joints: Vec<(&str, &str, &str, &str, &str)> = chain
        .iter()
        .map(|(j, p, c)| (j.as_str(), "revolute", p.as_str(), c.as_str(), ""))
        .collect();
    assert!(refused(&urdf_of(&joints)).contains("13 movable joints; dynid handles at most 12"));
}

#[test]
fn suspicious_inertias_are_kept_with_a_warning() {
    // Principal moments 0.01, 0.01, 0.05 break the triangle inequality; `b` has no <inertial>.
    let urdf = r#"<robot name="t"><link name="a"/><link name="b"/>
      <link name="c"><inertial><mass value="1"/>
        <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.05"/></inertial></link>
      <joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/></joint>
      <joint name="j2" type="revolute"><parent link="b"/><child link="c"/><origin xyz="0.5 0 0"/><axis xyz="0 0 1"/></joint>
    </robot>"#;
    let arm = import(urdf, &ImportOptions::default()).unwrap();
    let warnings = arm.warnings.join("\n");
    assert!(
        warnings.contains("t.urdf: <link name=\"c\"> <inertial>: principal moments"),
        "{warnings}"
    );
    assert!(warnings.contains("D-H link 1 has no mass"), "{warnings}");
    assert!(
        arm.notes
            .join("\n")
            .contains("massless (no <inertial> or zero mass): b"),
        "{:?}",
        arm.notes
    );
    assert!(arm.params_toml.contains("allow_nonphysical = true"));
    assert_eq!(arm.params.links[1].inertia_com[5], 0.05, "kept as given");
}

// ---------------------------------------------------------------------------------------------
// Command line.

#[test]
fn cli_imports_exports_and_computes_torques() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let urdf = d.join("robot.urdf");
    std::fs::write(&urdf, arm_with_gripper()).unwrap();
    let out = d.join("out");
    let o = dynid(&[
        "import-urdf",
        urdf.to_str().unwrap(),
        "--gravity",
        "-9.81,0,0",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(summary["name"], "robot");
    assert_eq!(summary["chain"], serde_json::json!(["j1", "j2"]));
    let dh = out.join("robot.toml");
    let params = out.join("robot.params.toml");
    assert!(dh.exists() && params.exists());

    // The written files feed `dynid torque` (reference dynamics) and `export-urdf` directly.
    let data = d.join("data.csv");
    std::fs::write(
        &data,
        "t,q1,q2,dq1,dq2,ddq1,ddq2\n0,0.1,0.2,0.3,0.4,0.5,0.6\n",
    )
    .unwrap();
    let (dh, params, data) = (
        dh.to_str().unwrap(),
        params.to_str().unwrap(),
        data.to_str().unwrap(),
    );
    let o = dynid(&["torque", "--arm", dh, "--params", params, "--data", data]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = dynid(&["export-urdf", "--arm", dh, "--params", params]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("<robot name=\"robot\""));

    // Bad input: exit 2 with the file named; nothing written.
    let bad = d.join("bad.urdf");
    std::fs::write(&bad, "<robot name=\"bad\"><link name=\"a\"/></robot>").unwrap();
    let o = dynid(&[
        "import-urdf",
        bad.to_str().unwrap(),
        "--out",
        d.join("none").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("bad.urdf: no movable joint"));
    assert!(!d.join("none").exists());
    let o = dynid(&[
        "import-urdf",
        urdf.to_str().unwrap(),
        "--gravity",
        "1,2",
        "--out",
        d.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
}

// ---------------------------------------------------------------------------------------------
// Pinocchio on real robots.

/// `None` (with the reason) unless the project's Python can import pinocchio and
/// example-robot-data is there.
fn pinocchio_unavailable(python: &Path, script: &Path) -> Option<String> {
    match Command::new(python).arg(script).arg("--check").output() {
        Ok(o) if o.status.success() => None,
        Ok(o) => Some(format!(
            "{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        )),
        Err(e) => Some(format!("{}: {e}", python.display())),
    }
}

fn run_pinocchio_check(extra: &[&str]) {
    let script =
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("tests/pinocchio/check_urdf.py");
    let python = project_python();
    // Never a silent pass: the test command (scripts/test.sh) installs Pinocchio into .venv/.
    if let Some(why) = pinocchio_unavailable(&python, &script) {
        panic!(
            "the Pinocchio comparison cannot run with {}: {} — run scripts/test.sh (it sets up .venv/ \
             with the pinned Pinocchio), or set DYNID_PYTHON to an interpreter that has \
             `pip install -r requirements.txt`",
            python.display(),
            why.trim()
        );
    }
    let o = Command::new(&python)
        .arg(&script)
        .args(["--dynid", env!("CARGO_BIN_EXE_dynid")])
        .args(extra)
        .output()
        .expect("run check_urdf.py");
    let report = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    eprintln!("{report}");
    assert!(
        o.status.success(),
        "dynid disagrees with Pinocchio:\n{report}"
    );
}

#[test]
fn torques_of_imported_robots_equal_pinocchio_rnea() {
    run_pinocchio_check(&[]);
}

/// The same through generated kernels: builds a copy of the crate with the imported arms in
/// `arms/` (minutes): `cargo test --test it -- --ignored generated_kernels_of_imported`.
#[test]
#[ignore]
fn generated_kernels_of_imported_robots_equal_pinocchio_rnea() {
    let cases = ["ur5", "panda", "double_pendulum", "kinova", "so100"];
    let mut args = vec!["--kernels"];
    for c in &cases {
        args.extend(["--case", c]);
    }
    run_pinocchio_check(&args);
}
