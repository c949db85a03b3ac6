//! `identified.urdf` is the user's URDF with new inertials: `urdf::roundtrip::rewrite` on every
//! URDF the project ships (data/urdf/, TIAGo) and on random trees with every joint kind, locked
//! and fixed bodies, links without `<inertial>`, a mimic gripper. (The example-robot-data URDFs
//! the tests import go through `identify` and Pinocchio in python/tests/test_roundtrip.py.) The oracles: (1) the rewritten
//! file, imported again, has exactly the dynamics of the parameters written into it (the import
//! is itself checked against a URDF-native Newton–Euler and Pinocchio in `urdf.rs`); (2) its
//! XML tree equals the original's once `<inertial>` and `<dynamics>` are taken out.

use dynid::params::{Effects, InertialParams};
use dynid::urdf::{import_str, roundtrip, ImportOptions};
use rand::Rng;

use super::urdf::{arm_with_gripper, random_robot, reference_torques, tip_of};
use crate::common::*;

/// A physically consistent random link: a cloud of point masses around a random centre.
fn random_link(rng: &mut impl Rng) -> [f64; 10] {
    let centre = [(); 3].map(|_| rng.gen_range(-0.3..0.3));
    let mut p = [0.0; 10];
    for _ in 0..6 {
        let m: f64 = rng.gen_range(0.05..2.0);
        let r = centre.map(|c| c + rng.gen_range(-0.1..0.1));
        let [x, y, z] = r;
        // Second moments about the frame origin (tensor entries, ixy = -Σ m·x·y).
        let add = [
            m * (y * y + z * z),
            -m * x * y,
            -m * x * z,
            m * (x * x + z * z),
            -m * y * z,
            m * (x * x + y * y),
            m * x,
            m * y,
            m * z,
            m,
        ];
        p.iter_mut().zip(add).for_each(|(a, b)| *a += b);
    }
    p
}

fn random_params(rng: &mut impl Rng, dof: usize) -> InertialParams {
    let full: Vec<f64> = (0..dof).flat_map(|_| random_link(rng)).collect();
    let effects = Effects {
        viscous: Some((0..dof).map(|_| rng.gen_range(0.0..3.0)).collect()),
        coulomb: Some((0..dof).map(|_| rng.gen_range(0.0..2.0)).collect()),
        ..Effects::default()
    };
    InertialParams::from_full_vector(&full, effects)
}

/// The robot's XML tree without `<inertial>`/`<dynamics>` children and whitespace-only text.
fn stripped(text: &str) -> xml::Element {
    fn clean(e: &mut xml::Element, depth: usize) {
        e.children.retain(|c| match c {
            xml::Xml::CharacterNode(t) => !t.trim().is_empty(),
            xml::Xml::ElementNode(c) => {
                !(depth == 1 && (c.name == "inertial" || c.name == "dynamics"))
            }
            _ => true,
        });
        for c in e.children.iter_mut() {
            if let xml::Xml::ElementNode(c) = c {
                clean(c, depth + 1);
            }
        }
    }
    let mut root: xml::Element = text.parse().expect("the URDF parses as XML");
    clean(&mut root, 0);
    root
}

/// Writes random parameters into `text` and checks both oracles; returns the rewritten URDF.
fn check(text: &str, origin: &str, opts: &ImportOptions, rng: &mut impl Rng) -> String {
    let arm = import_str(text, origin, opts).unwrap();
    let dof = arm.table.dof();
    let params = random_params(rng, dof);
    let out = roundtrip::rewrite(text, origin, opts, &params).unwrap();
    let back = import_str(&out.urdf, origin, opts)
        .unwrap_or_else(|e| panic!("{origin}: the rewritten URDF does not import: {e}"));
    assert_eq!(
        back.table, arm.table,
        "{origin}: the chain's geometry changed"
    );
    assert_eq!(back.chain, arm.chain);
    let (want, got) = (params.full_vector(), back.params.full_vector());
    for _ in 0..4 {
        let (q, dq, ddq) = random_state(rng, dof);
        let a = reference_torques(&arm.table, &want, &q, &dq, &ddq);
        let b = reference_torques(&arm.table, &got, &q, &dq, &ddq);
        assert_close(&b, &a, 1e-10, &format!("{origin}: τ of the rewritten URDF"));
    }
    assert_eq!(
        stripped(&out.urdf),
        stripped(text),
        "{origin}: elements other than <inertial>/<dynamics> changed"
    );
    let robot = urdf_rs::read_from_string(&out.urdf).unwrap();
    for (k, name) in arm.chain.iter().enumerate() {
        let j = robot.joints.iter().find(|j| &j.name == name).unwrap();
        let d = j.dynamics.as_ref().expect("<dynamics> written");
        assert_eq!(d.damping, params.effects.viscous.as_ref().unwrap()[k]);
        assert_eq!(d.friction, params.effects.coulomb.as_ref().unwrap()[k]);
    }
    out.urdf
}

#[test]
fn tiago_keeps_everything_but_the_moving_inertials() {
    let path = concat!(
        concat!(env!("CARGO_MANIFEST_DIR"), "/.."),
        "/data/real/tiago_figaroh/tiago.urdf"
    );
    let text = std::fs::read_to_string(path).unwrap();
    let out = check(&text, path, &ImportOptions::default(), &mut rng(39));
    // Comments outside the replaced <inertial> elements are kept (TIAGo has one inside one).
    let outside = |t: &str| {
        let mut n = 0;
        for part in t.split("</inertial>") {
            let head = part.split("<inertial>").next().unwrap_or("");
            n += head.matches("<!--").count();
        }
        n
    };
    assert_eq!(outside(&out), outside(&text));
    assert_eq!(
        text.matches("<!--").count() - out.matches("<!--").count(),
        1
    );
    assert!(out.len() > text.len() / 2);
}

#[test]
fn the_arm_urdfs_of_data_urdf_round_trip() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/urdf");
    let mut rng = rng(3940);
    let mut seen = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "urdf") {
            let text = std::fs::read_to_string(&path).unwrap();
            let origin = path.display().to_string();
            check(&text, &origin, &ImportOptions::default(), &mut rng);
            seen.push(origin);
        }
    }
    assert!(seen.len() >= 3, "{seen:?}");
}

#[test]
fn random_trees_with_locked_and_fixed_bodies_round_trip() {
    let mut rng = rng(3939);
    for case in 0..30 {
        let dof = 1 + case % 6;
        let robot = random_robot(&mut rng, dof);
        let opts = ImportOptions {
            tip: Some(tip_of(&robot)),
            ..Default::default()
        };
        check(
            &robot.urdf(),
            &format!("random{case}.urdf"),
            &opts,
            &mut rng,
        );
    }
}

#[test]
fn a_gripper_and_self_closing_links_round_trip() {
    let mut rng = rng(7);
    check(
        &arm_with_gripper(),
        "gripper.urdf",
        &ImportOptions::default(),
        &mut rng,
    );
    let bare = r#"<?xml version="1.0"?>
<!-- a comment before the robot -->
<robot name="bare">
  <link name="base"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="10" velocity="2"/></joint>
  <link name="l1"/>
  <joint name="j2" type="continuous">
    <origin xyz="0.3 0 0.1" rpy="0.2 0 0"/>
    <parent link="l1"/>
    <child link="l2"/>
    <axis xyz="0 1 0"/>
    <dynamics damping="0.5"/>
  </joint>
  <link name="l2"></link>
  <gazebo reference="l2"><material>Gazebo/Red</material></gazebo>
</robot>
"#;
    let out = check(bare, "bare.urdf", &ImportOptions::default(), &mut rng);
    assert!(out.starts_with("<?xml version=\"1.0\"?>\n<!-- a comment before the robot -->\n"));
}
