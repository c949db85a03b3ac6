//! The URDF's kinematic tree: validated structure, zero-pose link frames and chain selection.

use std::collections::HashMap;

use nalgebra::Vector3;
use urdf_rs::{JointType, Robot};

use super::geom::Pose;
use super::UrdfErrorKind as K;

/// How a joint moves, for the conversion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Motion {
    Revolute,
    Prismatic,
    Fixed,
    /// Floating, planar or spherical (named).
    Unsupported(&'static str),
}

impl Motion {
    fn of(t: &JointType) -> Motion {
        match t {
            JointType::Revolute | JointType::Continuous => Motion::Revolute,
            JointType::Prismatic => Motion::Prismatic,
            JointType::Fixed => Motion::Fixed,
            JointType::Floating => Motion::Unsupported("floating"),
            JointType::Planar => Motion::Unsupported("planar"),
            JointType::Spherical => Motion::Unsupported("spherical"),
        }
    }
}

/// The validated tree (indices into `robot.links` / `robot.joints`).
#[derive(Debug)]
pub(crate) struct Tree<'a> {
    pub robot: &'a Robot,
    pub motion: Vec<Motion>,
    /// Per link: the joint it hangs from (`None` for the root).
    pub parent_joint: Vec<Option<usize>>,
    /// Per joint: (parent link, child link).
    pub ends: Vec<(usize, usize)>,
    /// Per link: the joints hanging from it, in file order.
    pub children: Vec<Vec<usize>>,
    pub root: usize,
    /// Per joint: the joint it mimics, if any.
    pub mimics: Vec<Option<usize>>,
    /// Per joint: true when some joint mimics it.
    pub mimicked: Vec<bool>,
    by_name: HashMap<&'a str, usize>,
}

impl<'a> Tree<'a> {
    pub fn new(robot: &'a Robot) -> Result<Self, K> {
        let mut by_name = HashMap::new();
        for (i, l) in robot.links.iter().enumerate() {
            if by_name.insert(l.name.as_str(), i).is_some() {
                return Err(K::Duplicate {
                    element: "link",
                    name: l.name.clone(),
                });
            }
        }
        let mut joint_names = HashMap::new();
        for (i, j) in robot.joints.iter().enumerate() {
            if joint_names.insert(j.name.as_str(), i).is_some() {
                return Err(K::Duplicate {
                    element: "joint",
                    name: j.name.clone(),
                });
            }
        }
        let n = robot.links.len();
        let mut parents: Vec<Vec<usize>> = vec![Vec::new(); n];
        let mut children = vec![Vec::new(); n];
        let mut ends = Vec::with_capacity(robot.joints.len());
        for (i, j) in robot.joints.iter().enumerate() {
            let find = |role: &'static str, link: &str| {
                by_name.get(link).copied().ok_or_else(|| K::MissingLink {
                    joint: j.name.clone(),
                    role,
                    link: link.to_string(),
                })
            };
            let parent = find("parent", &j.parent.link)?;
            let child = find("child", &j.child.link)?;
            parents[child].push(i);
            children[parent].push(i);
            ends.push((parent, child));
        }
        for (l, ps) in parents.iter().enumerate() {
            if ps.len() > 1 {
                return Err(K::ClosedLoop {
                    link: robot.links[l].name.clone(),
                    joints: ps.iter().map(|&j| robot.joints[j].name.clone()).collect(),
                });
            }
        }
        let roots: Vec<usize> = (0..n).filter(|&l| parents[l].is_empty()).collect();
        let root = match roots.as_slice() {
            [] => return Err(K::NoRoot),
            [r] => *r,
            _ => {
                return Err(K::SeveralRoots {
                    roots: roots.iter().map(|&l| robot.links[l].name.clone()).collect(),
                })
            }
        };
        let parent_joint: Vec<Option<usize>> = parents.iter().map(|p| p.first().copied()).collect();
        // One root and one parent per link: a link not reached from the root sits on a cycle.
        let mut reached = vec![false; n];
        let mut stack = vec![root];
        while let Some(l) = stack.pop() {
            reached[l] = true;
            stack.extend(children[l].iter().map(|&j| ends[j].1));
        }
        if let Some(l) = reached.iter().position(|&r| !r) {
            let joint = parent_joint[l]
                .map(|j| robot.joints[j].name.clone())
                .unwrap_or_default();
            return Err(K::ClosedLoop {
                link: robot.links[l].name.clone(),
                joints: vec![joint],
            });
        }
        let mut mimics = vec![None; robot.joints.len()];
        let mut mimicked = vec![false; robot.joints.len()];
        for (i, j) in robot.joints.iter().enumerate() {
            if let Some(m) = &j.mimic {
                // A mimic of an unknown joint is still a coupled joint; it just has no master here.
                if let Some(&master) = joint_names.get(m.joint.as_str()) {
                    mimicked[master] = true;
                    mimics[i] = Some(master);
                } else {
                    mimics[i] = Some(i);
                }
            }
        }
        let motion = robot
            .joints
            .iter()
            .map(|j| Motion::of(&j.joint_type))
            .collect();
        Ok(Tree {
            robot,
            motion,
            parent_joint,
            ends,
            children,
            root,
            mimics,
            mimicked,
            by_name,
        })
    }

    pub fn link_name(&self, l: usize) -> &'a str {
        &self.robot.links[l].name
    }

    pub fn joint_name(&self, j: usize) -> &'a str {
        &self.robot.joints[j].name
    }

    /// The link called `name`, for `--base` / `--tip`.
    pub fn find_link(&self, option: &'static str, name: &str) -> Result<usize, K> {
        self.by_name.get(name).copied().ok_or_else(|| {
            let names: Vec<&str> = self.by_name.keys().copied().collect();
            K::UnknownOptionLink {
                option,
                name: name.to_string(),
                suggestion: crate::diag::did_you_mean(name, &names).map(str::to_string),
            }
        })
    }

    /// Zero-pose frame of every link in the root frame (all joints at 0).
    pub fn zero_poses(&self) -> Vec<Pose> {
        let mut poses = vec![Pose::identity(); self.robot.links.len()];
        let mut stack = vec![self.root];
        while let Some(l) = stack.pop() {
            for &j in &self.children[l] {
                let o = &self.robot.joints[j].origin;
                let child = self.ends[j].1;
                poses[child] = poses[l].then(&Pose::from_xyz_rpy(*o.xyz, *o.rpy));
                stack.push(child);
            }
        }
        poses
    }

    /// The unit axis of a movable joint in its own frame.
    pub fn axis(&self, j: usize) -> Result<Vector3<f64>, K> {
        let a = Vector3::from(*self.robot.joints[j].axis.xyz);
        let n = a.norm();
        if n == 0.0 || !n.is_finite() {
            return Err(K::ZeroAxis {
                joint: self.joint_name(j).to_string(),
            });
        }
        Ok(a / n)
    }

    /// Joints from `base` down to `tip` (`None` when `tip` does not descend from `base`).
    pub fn path(&self, base: usize, tip: usize) -> Option<Vec<usize>> {
        let mut joints = Vec::new();
        let mut l = tip;
        while l != base {
            let j = self.parent_joint[l]?;
            joints.push(j);
            l = self.ends[j].0;
        }
        joints.reverse();
        Some(joints)
    }

    /// True for a joint that may be one of the chain's D-H joints when choosing the default
    /// chain: movable (unsupported kinds count, so that they are reported) and not coupled by
    /// `<mimic>`.
    fn counts(&self, j: usize) -> bool {
        self.motion[j] != Motion::Fixed && self.mimics[j].is_none() && !self.mimicked[j]
    }

    /// The movable joints of the chain from `base` to `tip` (or to the default tip), checked,
    /// and the tip link.
    pub fn chain(&self, base: usize, tip: Option<usize>) -> Result<(Vec<usize>, usize), K> {
        let (path, tip) = match tip {
            Some(t) => {
                let path = self.path(base, t).ok_or_else(|| K::TipNotBelowBase {
                    base: self.link_name(base).to_string(),
                    tip: self.link_name(t).to_string(),
                })?;
                (path, t)
            }
            None => self.default_chain(base)?,
        };
        let movable: Vec<usize> = path
            .into_iter()
            .filter(|&j| self.motion[j] != Motion::Fixed)
            .collect();
        if movable.is_empty() {
            return Err(K::NoMovableJoint {
                base: self.link_name(base).to_string(),
                tip: Some(self.link_name(tip).to_string()),
            });
        }
        for &j in &movable {
            if let Motion::Unsupported(kind) = self.motion[j] {
                return Err(K::UnsupportedJoint {
                    joint: self.joint_name(j).to_string(),
                    kind,
                });
            }
            let coupled = match &self.robot.joints[j].mimic {
                Some(m) => Some((j, m.joint.clone())),
                None if self.mimicked[j] => self
                    .mimics
                    .iter()
                    .position(|&m| m == Some(j))
                    .map(|f| (f, self.joint_name(j).to_string())),
                None => None,
            };
            if let Some((follower, master)) = coupled {
                return Err(K::Mimic {
                    joint: self.joint_name(j).to_string(),
                    follower: self.joint_name(follower).to_string(),
                    master,
                });
            }
        }
        Ok((movable, tip))
    }

    /// The first non-fixed joint below `link` (depth first, file order).
    fn first_movable(&self, link: usize) -> Option<usize> {
        self.children[link].iter().find_map(|&j| {
            if self.motion[j] != Motion::Fixed {
                Some(j)
            } else {
                self.first_movable(self.ends[j].1)
            }
        })
    }

    /// Default tip: the chain to the leaf with the most counting joints, ending at the link
    /// moved by its last one; refused when two different chains tie.
    fn default_chain(&self, base: usize) -> Result<(Vec<usize>, usize), K> {
        // (link, counting joints so far, last counting joint) for every leaf below `base`.
        let mut best: Vec<Option<usize>> = Vec::new();
        let mut best_count = 0;
        let mut stack = vec![(base, 0usize, None::<usize>)];
        while let Some((l, count, last)) = stack.pop() {
            if self.children[l].is_empty() {
                if count > best_count {
                    best_count = count;
                    best.clear();
                }
                if count == best_count && !best.contains(&last) {
                    best.push(last);
                }
                continue;
            }
            for &j in &self.children[l] {
                let (c, last) = if self.counts(j) {
                    (count + 1, Some(j))
                } else {
                    (count, last)
                };
                stack.push((self.ends[j].1, c, last));
            }
        }
        let lasts: Vec<usize> = best.into_iter().flatten().collect();
        match lasts.as_slice() {
            // Only coupled joints below the base: the chain to the first one, refused by the
            // caller with the reason.
            [] => match self.first_movable(base) {
                Some(j) => {
                    let tip = self.ends[j].1;
                    Ok((self.path(base, tip).unwrap_or_default(), tip))
                }
                None => Err(K::NoMovableJoint {
                    base: self.link_name(base).to_string(),
                    tip: None,
                }),
            },
            [j] => {
                let tip = self.ends[*j].1;
                // `tip` descends from `base` by construction.
                let path = self.path(base, tip).unwrap_or_default();
                Ok((path, tip))
            }
            many => {
                let mut tips: Vec<String> = many
                    .iter()
                    .map(|&j| self.link_name(self.ends[j].1).to_string())
                    .collect();
                tips.sort();
                Err(K::AmbiguousChain {
                    joints: best_count,
                    tips,
                })
            }
        }
    }
}
