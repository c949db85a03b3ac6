//! URDF → D-H table + inertial parameters (the pipeline; the choices are in [`super`]'s docs).

use std::collections::HashSet;
use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Matrix3, Vector3};
use urdf_rs::{JointType, Robot};

use super::frames::{self, AxisLine, Row};
use super::geom::{six, tensor, Pose};
use super::lump::{lump, Body};
use super::tree::{Motion, Tree};
use super::{ImportOptions, Imported, UrdfError, UrdfErrorKind as K, DEFAULT_GRAVITY};
use crate::dh::{DhTable, Joint, JointKind, MAX_JOINTS};
use crate::params::{check_physical, InertialParams, ParamsOptions};

/// Above this (m or rad) a D-H row that does not reproduce the URDF geometry is a bug.
const RESIDUAL_BUG: f64 = 1e-6;
/// Above this the (tiny) mismatch from nearly parallel axes is reported.
const RESIDUAL_WARN: f64 = 1e-10;

/// Converts the URDF file at `path` (errors name it as given).
pub fn import_file(path: &Path, opts: &ImportOptions) -> Result<Imported, UrdfError> {
    let file = path.display().to_string();
    let err = |kind| UrdfError {
        file: file.clone(),
        kind,
    };
    let bytes = std::fs::read(path).map_err(|e| err(K::Io(e)))?;
    let text = String::from_utf8(bytes).map_err(|e| {
        err(K::Io(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            e,
        )))
    })?;
    import_str(&text, &file, opts)
}

/// Converts URDF text; `origin` (usually the file path) names it in errors and gives the
/// default arm name (its file stem).
pub fn import_str(text: &str, origin: &str, opts: &ImportOptions) -> Result<Imported, UrdfError> {
    convert(text, origin, opts).map_err(|kind| UrdfError {
        file: origin.to_string(),
        kind,
    })
}

/// Where a link's body goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Owner {
    /// Not below the base: not part of the arm.
    Outside,
    /// Fixed to the base (or locked onto it): does not move.
    Ground,
    /// Moves with D-H link `k` (0-based).
    Link(usize),
}

fn convert(text: &str, origin: &str, opts: &ImportOptions) -> Result<Imported, K> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let with_inertial = prescan(text)?;
    let robot = urdf_rs::read_from_string(text).map_err(|e| K::Parse(e.to_string()))?;
    check_finite(&robot)?;
    let tree = Tree::new(&robot)?;
    let base = match &opts.base {
        Some(b) => tree.find_link("--base", b)?,
        None => tree.root,
    };
    let tip = opts
        .tip
        .as_deref()
        .map(|t| tree.find_link("--tip", t))
        .transpose()?;
    let (chain, tip) = tree.chain(base, tip)?;
    if chain.len() > MAX_JOINTS {
        return Err(K::TooManyJoints { count: chain.len() });
    }
    let name = arm_name(opts.name.as_deref(), origin, &robot.name)?;
    let file = Path::new(origin)
        .file_name()
        .map_or_else(|| origin.to_string(), |f| f.to_string_lossy().into_owned());

    // Zero-pose frames in base coordinates.
    let root_poses = tree.zero_poses();
    let base_inv = root_poses[base].inverse();
    let poses: Vec<Pose> = root_poses.iter().map(|p| base_inv.then(p)).collect();

    let mut warnings = Vec::new();
    let mut notes = Vec::new();
    let Fitted {
        lines,
        frames,
        rows,
    } = dh_frames(&tree, &chain, &poses, origin, &mut warnings)?;

    let owner = owners(&tree, base, &chain);
    let (links, nonphysical) = bodies(
        &tree,
        &owner,
        &poses,
        &frames,
        &with_inertial,
        origin,
        &mut warnings,
        &mut notes,
    )?;

    let gravity_root = Vector3::from(opts.gravity.unwrap_or(DEFAULT_GRAVITY));
    let g = frames[0].r.transpose() * (root_poses[base].r.transpose() * gravity_root);
    let gravity = [clean(g.x), clean(g.y), clean(g.z)];

    let joints: Vec<Joint> = chain
        .iter()
        .zip(&lines)
        .zip(&rows)
        .map(|((&j, l), r)| table_joint(&robot, j, l.kind, r))
        .collect();
    let table = DhTable {
        name: name.clone(),
        convention: "modified".into(),
        gravity,
        joints,
    };

    describe(&tree, &owner, base, tip, &chain, &mut notes);
    let chain_names: Vec<String> = chain
        .iter()
        .map(|&j| tree.joint_name(j).to_string())
        .collect();
    let dh_toml = dh_text(&table, &tree, &chain, &file, base, tip, opts);
    let params_toml = params_text(&links, &tree, &chain, &owner, &file, &name, nonphysical);
    let placement = placements(&tree, &owner, &poses, &frames, &chain);

    // What we write must load with the project's own loaders.
    let check = DhTable::from_str(&dh_toml, &format!("{name}.toml"))
        .map_err(|e| K::Internal(e.to_string()))?;
    let params = InertialParams::from_str(
        &params_toml,
        &format!("{name}.params.toml"),
        check.dof(),
        &ParamsOptions {
            allow_nonphysical: nonphysical,
        },
    )
    .map_err(|e| K::Internal(e.to_string()))?;
    Ok(Imported {
        table: check,
        params,
        dh_toml,
        params_toml,
        chain: chain_names,
        notes,
        warnings,
        placement,
    })
}

/// Where each D-H link sits in its URDF links (what `roundtrip` inverts): frame `F_k` in the
/// frame of the link joint `k` moves, and the other bodies lumped into D-H link `k`.
fn placements(
    tree: &Tree<'_>,
    owner: &[Owner],
    poses: &[Pose],
    frames: &[Pose],
    chain: &[usize],
) -> Vec<super::Placement> {
    chain
        .iter()
        .enumerate()
        .map(|(k, &j)| {
            let moved = tree.ends[j].1;
            let others = (0..owner.len())
                .filter(|&l| owner[l] == Owner::Link(k) && l != moved)
                .map(|l| {
                    let link = &tree.robot.links[l];
                    (link.name.clone(), body_in(link, &poses[l], &frames[k]))
                })
                .collect();
            super::Placement {
                link: tree.link_name(moved).to_string(),
                dh_in_link: poses[moved].inverse().then(&frames[k]),
                others,
            }
        })
        .collect()
}

/// A URDF link's body in frame `frame` (both poses in base coordinates).
fn body_in(link: &urdf_rs::Link, pose: &Pose, frame: &Pose) -> Body {
    let i = &link.inertial;
    let n = &i.inertia;
    let inertial = pose.then(&Pose::from_xyz_rpy(*i.origin.xyz, *i.origin.rpy));
    let in_frame = frame.inverse().then(&inertial);
    let local = [n.ixx, n.ixy, n.ixz, n.iyy, n.iyz, n.izz];
    Body {
        m: i.mass.value,
        com: in_frame.p,
        inertia: in_frame.r * tensor(local) * in_frame.r.transpose(),
    }
}

/// The chain's axes at the zero pose, their D-H frames `F_1..F_n` (base coordinates) and rows.
struct Fitted {
    lines: Vec<AxisLine>,
    frames: Vec<Pose>,
    rows: Vec<Row>,
}

/// The chain's axes at the zero pose (base coordinates), their D-H frames and rows; a row that
/// does not reproduce the URDF geometry is a bug, a small mismatch (nearly parallel axes) a
/// warning.
fn dh_frames(
    tree: &Tree<'_>,
    chain: &[usize],
    poses: &[Pose],
    origin: &str,
    warnings: &mut Vec<String>,
) -> Result<Fitted, K> {
    let mut lines = Vec::with_capacity(chain.len());
    for &j in chain {
        let link = poses[tree.ends[j].1];
        let kind = if tree.motion[j] == Motion::Prismatic {
            JointKind::Prismatic
        } else {
            JointKind::Revolute
        };
        lines.push(AxisLine {
            kind,
            point: link.p,
            dir: link.r * tree.axis(j)?,
            link,
        });
    }
    let (frames, rows, residual) = frames::fit(&lines);
    if residual.is_nan() || residual > RESIDUAL_BUG {
        return Err(K::Internal(format!(
            "D-H rows miss the URDF frames by {residual:e}"
        )));
    }
    if residual > RESIDUAL_WARN {
        warnings.push(format!(
            "{origin}: consecutive joint axes are parallel to within {:e} rad but not exactly: treated as parallel, the D-H table misses the URDF geometry by up to {residual:e} (m or rad)",
            super::PARALLEL_TOL
        ));
    }
    Ok(Fitted {
        lines,
        frames,
        rows,
    })
}

/// Pre-scan with the XML tree urdf-rs itself parses with, for messages that name the element:
/// unknown joint types, and which links have an `<inertial>`.
fn prescan(text: &str) -> Result<HashSet<String>, K> {
    let root: xml::Element = text
        .parse()
        .map_err(|e: xml::BuilderError| K::Parse(e.to_string()))?;
    if uses_xacro(&root) {
        return Err(K::Xacro);
    }
    const TYPES: [&str; 7] = [
        "revolute",
        "continuous",
        "prismatic",
        "fixed",
        "floating",
        "planar",
        "spherical",
    ];
    let mut with_inertial = HashSet::new();
    for child in root.children.iter() {
        let xml::Xml::ElementNode(e) = child else {
            continue;
        };
        let name = e.get_attribute("name", None).unwrap_or_default();
        match e.name.as_str() {
            "joint" => {
                if let Some(t) = e.get_attribute("type", None) {
                    if !TYPES.contains(&t) {
                        return Err(K::UnknownJointType {
                            joint: name.to_string(),
                            found: t.to_string(),
                        });
                    }
                }
            }
            "link" if e.get_child("inertial", None).is_some() => {
                with_inertial.insert(name.to_string());
            }
            _ => {}
        }
    }
    Ok(with_inertial)
}

/// True when some element is in the xacro namespace (`<xacro:macro>`, `<xacro:include>`, ...).
fn uses_xacro(e: &xml::Element) -> bool {
    e.ns.as_deref().is_some_and(|ns| ns.contains("xacro"))
        || e.children
            .iter()
            .any(|c| matches!(c, xml::Xml::ElementNode(child) if uses_xacro(child)))
}

fn check_finite(robot: &Robot) -> Result<(), K> {
    let bad = |element: String, what: &'static str| K::NonFinite { element, what };
    let all = |v: &[f64]| v.iter().all(|x| x.is_finite());
    for j in &robot.joints {
        let el = || format!("<joint name=\"{}\">", j.name);
        if !all(&*j.origin.xyz) || !all(&*j.origin.rpy) {
            return Err(bad(el(), "<origin>"));
        }
        if !all(&*j.axis.xyz) {
            return Err(bad(el(), "<axis xyz>"));
        }
    }
    for l in &robot.links {
        let i = &l.inertial;
        let n = &i.inertia;
        if !all(&*i.origin.xyz)
            || !all(&*i.origin.rpy)
            || !i.mass.value.is_finite()
            || !all(&[n.ixx, n.ixy, n.ixz, n.iyy, n.iyz, n.izz])
        {
            return Err(bad(
                format!("<link name=\"{}\"> <inertial>", l.name),
                "a value",
            ));
        }
    }
    Ok(())
}

/// `--name`, or the file stem / robot name made a valid arm (Rust module) name.
fn arm_name(given: Option<&str>, origin: &str, robot: &str) -> Result<String, K> {
    if let Some(name) = given {
        let ok = name.starts_with(|c: char| c.is_ascii_lowercase())
            && name
                .chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
            && !KEYWORDS.contains(&name);
        return if ok {
            Ok(name.to_string())
        } else {
            Err(K::BadName {
                name: name.to_string(),
            })
        };
    }
    let stem = Path::new(origin)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let raw = if stem.is_empty() {
        robot
    } else {
        stem.as_str()
    };
    let mut name = String::new();
    for c in raw.chars().flat_map(char::to_lowercase) {
        let c = if c.is_ascii_alphanumeric() { c } else { '_' };
        if !(c == '_' && (name.is_empty() || name.ends_with('_'))) {
            name.push(c);
        }
    }
    let mut name = name.trim_end_matches('_').to_string();
    if name.is_empty() {
        name = "urdf_arm".into();
    } else if name.starts_with(|c: char| c.is_ascii_digit()) {
        name = format!("arm_{name}");
    }
    if KEYWORDS.contains(&name.as_str()) {
        name.push_str("_arm");
    }
    Ok(name)
}

/// Rust keywords: an arm name becomes a module name.
const KEYWORDS: [&str; 52] = [
    "as", "async", "await", "break", "const", "continue", "crate", "dyn", "else", "enum", "extern",
    "false", "fn", "for", "if", "impl", "in", "let", "loop", "match", "mod", "move", "mut", "pub",
    "ref", "return", "self", "static", "struct", "super", "trait", "true", "type", "unsafe", "use",
    "where", "while", "abstract", "become", "box", "do", "final", "macro", "override", "priv",
    "typeof", "unsized", "virtual", "yield", "try", "gen", "union",
];

fn owners(tree: &Tree<'_>, base: usize, chain: &[usize]) -> Vec<Owner> {
    let mut owner = vec![Owner::Outside; tree.robot.links.len()];
    owner[tree.root] = if tree.root == base {
        Owner::Ground
    } else {
        Owner::Outside
    };
    let mut stack = vec![tree.root];
    while let Some(l) = stack.pop() {
        for &j in &tree.children[l] {
            let c = tree.ends[j].1;
            owner[c] = match chain.iter().position(|&k| k == j) {
                Some(k) => Owner::Link(k),
                None if c == base => Owner::Ground,
                None => owner[l],
            };
            stack.push(c);
        }
    }
    owner
}

/// The lumped body of each D-H link in its own frame, and whether any input inertia was
/// non-physical (warned).
#[allow(clippy::too_many_arguments)]
fn bodies(
    tree: &Tree<'_>,
    owner: &[Owner],
    poses: &[Pose],
    frames: &[Pose],
    with_inertial: &HashSet<String>,
    origin: &str,
    warnings: &mut Vec<String>,
    notes: &mut Vec<String>,
) -> Result<(Vec<Body>, bool), K> {
    let mut parts: Vec<Vec<Body>> = vec![Vec::new(); frames.len()];
    let mut nonphysical = false;
    let mut massless = Vec::new();
    for (l, link) in tree.robot.links.iter().enumerate() {
        let Owner::Link(k) = owner[l] else { continue };
        let i = &link.inertial;
        let m = i.mass.value;
        if m < 0.0 {
            return Err(K::NegativeMass {
                link: link.name.clone(),
                m,
            });
        }
        let n = &i.inertia;
        let local = [n.ixx, n.ixy, n.ixz, n.iyy, n.iyz, n.izz];
        if !with_inertial.contains(&link.name) || m == 0.0 {
            massless.push(link.name.clone());
        }
        if let Err(why) = check_physical(m, &local) {
            nonphysical = true;
            warnings.push(format!(
                "{origin}: <link name=\"{}\"> <inertial>: {why}",
                link.name
            ));
        }
        // Inertial frame in D-H frame k: rotate the tensor once, by the combined rotation.
        let inertial = poses[l].then(&Pose::from_xyz_rpy(*i.origin.xyz, *i.origin.rpy));
        let in_frame = frames[k].inverse().then(&inertial);
        let inertia: Matrix3<f64> = in_frame.r * tensor(local) * in_frame.r.transpose();
        parts[k].push(Body {
            m,
            com: in_frame.p,
            inertia,
        });
    }
    if !massless.is_empty() {
        let massless: Vec<&str> = massless.iter().map(String::as_str).collect();
        notes.push(format!(
            "massless (no <inertial> or zero mass): {}",
            name_list(&massless)
        ));
    }
    let links: Vec<Body> = parts.iter().map(|p| tidy(lump(p))).collect();
    for (k, b) in links.iter().enumerate() {
        if b.is_empty() {
            warnings.push(format!(
                "{origin}: D-H link {} has no mass or inertia (no URDF body moves with joint {}) — its parameters are all zero",
                k + 1,
                k + 1
            ));
        }
    }
    Ok((links, nonphysical))
}

/// Rounding noise from the frame changes (|x| below 1e-15 of the body's scale) becomes exact
/// zeros, so symmetric bodies read as such; the change is far below any tolerance.
fn tidy(mut b: Body) -> Body {
    let scale = b.inertia.amax();
    b.inertia
        .iter_mut()
        .filter(|v| v.abs() < 1e-15 * scale)
        .for_each(|v| *v = 0.0);
    b.com
        .iter_mut()
        .filter(|v| v.abs() < 1e-15)
        .for_each(|v| *v = 0.0);
    b
}

fn table_joint(robot: &Robot, j: usize, kind: JointKind, r: &Row) -> Joint {
    let uj = &robot.joints[j];
    let lim = &uj.limit;
    let positive = |v: f64| (v.is_finite() && v > 0.0).then_some(v);
    let (q_min, q_max) = if uj.joint_type != JointType::Continuous
        && lim.lower.is_finite()
        && lim.upper.is_finite()
        && lim.lower < lim.upper
    {
        (Some(lim.lower), Some(lim.upper))
    } else {
        (None, None)
    };
    Joint {
        // A name a D-H table cannot hold (a comma, surrounding spaces) is left out: such an arm
        // is matched to its recordings with `--joints`.
        name: (!uj.name.is_empty() && !uj.name.contains(',') && uj.name.trim() == uj.name)
            .then(|| uj.name.clone()),
        kind,
        alpha: r.alpha,
        a: r.a,
        d: r.d,
        theta: r.theta,
        q_min,
        q_max,
        dq_max: positive(lim.velocity),
        ddq_max: positive(lim.acceleration),
        tau_max: positive(lim.effort),
    }
}

/// Notes: the chain, the locked joints and what was dropped with the fixed base.
fn describe(
    tree: &Tree<'_>,
    owner: &[Owner],
    base: usize,
    tip: usize,
    chain: &[usize],
    notes: &mut Vec<String>,
) {
    let names: Vec<&str> = chain.iter().map(|&j| tree.joint_name(j)).collect();
    notes.insert(
        0,
        format!(
            "chain {} → {}: {} joints ({})",
            tree.link_name(base),
            tree.link_name(tip),
            chain.len(),
            names.join(", ")
        ),
    );
    let mut locked = Vec::new();
    let mut grounded = Vec::new();
    for (j, &(_, child)) in tree.ends.iter().enumerate() {
        if tree.motion[j] == Motion::Fixed || chain.contains(&j) {
            continue;
        }
        let mut what = tree.joint_name(j).to_string();
        if let Some(m) = &tree.robot.joints[j].mimic {
            if m.offset.is_some_and(|o| o != 0.0) {
                what.push_str(" (its <mimic> offset is ignored)");
            }
        }
        match owner[child] {
            Owner::Link(k) => locked.push(format!("{what} → link {}", k + 1)),
            Owner::Ground => grounded.push(what),
            Owner::Outside => {}
        }
    }
    if !locked.is_empty() {
        let locked: Vec<&str> = locked.iter().map(String::as_str).collect();
        notes.push(format!(
            "joints off the chain locked at 0 and lumped: {}",
            name_list(&locked)
        ));
    }
    let fixed_to_base: Vec<&str> = (0..owner.len())
        .filter(|&l| owner[l] == Owner::Ground && l != base)
        .map(|l| tree.link_name(l))
        .collect();
    let mut dropped = format!(
        "the base `{}` is fixed: its own inertia does not enter the dynamics and is not exported",
        tree.link_name(base)
    );
    if !fixed_to_base.is_empty() {
        let _ = write!(
            dropped,
            ", nor are the bodies attached to it ({})",
            name_list(&fixed_to_base)
        );
    }
    notes.push(dropped);
    if !grounded.is_empty() {
        let grounded: Vec<&str> = grounded.iter().map(String::as_str).collect();
        notes.push(format!(
            "joints attached to the fixed base, not on the chain (held at 0): {}",
            name_list(&grounded)
        ));
    }
    let outside = owner.iter().filter(|&&o| o == Owner::Outside).count();
    if outside > 0 {
        notes.push(format!(
            "{outside} links above or beside --base {} are not part of the arm (joints between the root and the base held at 0)",
            tree.link_name(base)
        ));
    }
    let damped: Vec<&str> = chain
        .iter()
        .filter(|&&j| {
            tree.robot.joints[j]
                .dynamics
                .as_ref()
                .is_some_and(|d| d.damping != 0.0 || d.friction != 0.0)
        })
        .map(|&j| tree.joint_name(j))
        .collect();
    if !damped.is_empty() {
        notes.push(format!(
            "<dynamics> damping/friction of {} not imported (identify them as effects: viscous, coulomb)",
            damped.join(", ")
        ));
    }
}

/// `a, b, c`, or the first few and a count when long.
fn name_list(items: &[&str]) -> String {
    const SHOWN: usize = 8;
    if items.len() <= SHOWN {
        return items.join(", ");
    }
    format!(
        "{}, … ({} more)",
        items[..SHOWN].join(", "),
        items.len() - SHOWN
    )
}

/// A float as TOML: shortest round-trip form, no negative zero.
fn num(v: f64) -> String {
    format!("{:?}", v + 0.0)
}

/// A TOML basic string.
fn quote(v: &str) -> String {
    toml::Value::String(v.to_string()).to_string()
}

fn clean(v: f64) -> f64 {
    if v.abs() < 1e-14 {
        0.0
    } else {
        v
    }
}

fn nums(v: &[f64]) -> String {
    let parts: Vec<String> = v.iter().map(|&x| num(x)).collect();
    format!("[{}]", parts.join(", "))
}

fn command(file: &str, base: Option<&str>, tip: Option<&str>, opts: &ImportOptions) -> String {
    let mut cmd = format!("dynid import-urdf {file}");
    if let Some(b) = base {
        let _ = write!(cmd, " --base {b}");
    }
    if let Some(t) = tip {
        let _ = write!(cmd, " --tip {t}");
    }
    if let Some(g) = opts.gravity {
        let _ = write!(cmd, " --gravity {},{},{}", num(g[0]), num(g[1]), num(g[2]));
    }
    if let Some(n) = &opts.name {
        let _ = write!(cmd, " --name {n}");
    }
    cmd + " --out DIR"
}

fn dh_text(
    table: &DhTable,
    tree: &Tree<'_>,
    chain: &[usize],
    file: &str,
    base: usize,
    tip: usize,
    opts: &ImportOptions,
) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Modified D-H table (Craig) imported from {file}: chain {} → {}.",
        tree.link_name(base),
        tree.link_name(tip)
    );
    s.push_str("# q = 0 is the URDF's zero pose and positive q its positive motion; frame 0 is frame 1 at q1 = 0.\n");
    let _ = writeln!(
        s,
        "# regenerate: {}",
        command(file, opts.base.as_deref(), opts.tip.as_deref(), opts)
    );
    let _ = writeln!(s, "name = {}", quote(&table.name));
    s.push_str("convention = \"modified\"\n");
    let _ = writeln!(s, "gravity = {}", nums(&table.gravity));
    for (k, (jt, &j)) in table.joints.iter().zip(chain).enumerate() {
        let uj = &tree.robot.joints[j];
        let ty = format!("{:?}", uj.joint_type).to_lowercase();
        let _ = writeln!(
            s,
            "\n# joint {}: URDF <joint name=\"{}\" type=\"{ty}\">, moves `{}`",
            k + 1,
            uj.name,
            uj.child.link
        );
        s.push_str("[[joint]]\n");
        if let Some(n) = &jt.name {
            let _ = writeln!(s, "name = {}", quote(n));
        }
        let kind = if jt.kind == JointKind::Prismatic {
            "prismatic"
        } else {
            "revolute"
        };
        let _ = writeln!(s, "kind = \"{kind}\"");
        for (key, v) in [
            ("alpha", jt.alpha),
            ("a", jt.a),
            ("d", jt.d),
            ("theta", jt.theta),
        ] {
            let _ = writeln!(s, "{key} = {}", num(v));
        }
        for (key, v) in [
            ("q_min", jt.q_min),
            ("q_max", jt.q_max),
            ("dq_max", jt.dq_max),
            ("ddq_max", jt.ddq_max),
            ("tau_max", jt.tau_max),
        ] {
            if let Some(v) = v {
                let _ = writeln!(s, "{key} = {}", num(v));
            }
        }
    }
    s
}

fn params_text(
    links: &[Body],
    tree: &Tree<'_>,
    chain: &[usize],
    owner: &[Owner],
    file: &str,
    name: &str,
    nonphysical: bool,
) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Inertial parameters imported from {file}, in the D-H link frames of {name}.toml."
    );
    s.push_str("# Each link is the URDF link its joint moves plus the bodies fixed to it; inertia_com holds tensor\n");
    s.push_str("# entries (ixx, ixy, ixz, iyy, iyz, izz) about the centre of mass, as in URDF (ixy = -∫xy dm).\n");
    if nonphysical {
        s.push_str("# Some URDF inertias are not physically possible (see the import warnings); kept as given:\n");
        s.push_str("allow_nonphysical = true\n");
    }
    for (k, (b, &j)) in links.iter().zip(chain).enumerate() {
        let moved = tree.ends[j].1;
        let others: Vec<&str> = (0..owner.len())
            .filter(|&l| owner[l] == Owner::Link(k) && l != moved)
            .map(|l| tree.link_name(l))
            .collect();
        s.push('\n');
        if !others.is_empty() {
            let _ = writeln!(s, "# link {} carries {}", k + 1, others.join(", "));
        }
        s.push_str("[[link]]\n");
        let _ = writeln!(s, "name = {}", quote(tree.link_name(moved)));
        let _ = writeln!(s, "m = {}", num(b.m));
        let _ = writeln!(s, "com = {}", nums(b.com.as_slice()));
        let _ = writeln!(s, "inertia_com = {}", nums(&six(&b.inertia)));
    }
    s
}
