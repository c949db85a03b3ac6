//! A rigid body added to the user's URDF as a new link on a fixed joint to the link the last
//! chain joint moves (the payload): the file's own text is kept and the new elements are
//! inserted before `</robot>`. The body comes in the last D-H frame and is re-expressed in that
//! URDF link's frame, as `roundtrip` does for the identified links.

use std::fmt::Write as _;

use nalgebra::Vector3;

use super::geom::{six, tensor};
use super::{import_str, ImportOptions, UrdfError, UrdfErrorKind};

/// `text` with a fixed link named `name` (suffixed `_2`, `_3`, … when taken) carrying mass `m`,
/// centre of mass `com` and inertia about it `inertia` (`[xx, xy, xz, yy, yz, zz]`), all in the
/// last D-H link's frame.
pub fn attach_body(
    text: &str,
    origin: &str,
    opts: &ImportOptions,
    name: &str,
    m: f64,
    com: [f64; 3],
    inertia: [f64; 6],
) -> Result<String, UrdfError> {
    let imported = import_str(text, origin, opts)?;
    let err = |msg: String| UrdfError {
        file: origin.to_string(),
        kind: UrdfErrorKind::Internal(msg),
    };
    let Some(last) = imported.placement.last() else {
        return Err(err(
            "the URDF chain has no joint to carry the payload".into()
        ));
    };
    let robot = urdf_rs::read_from_string(text).map_err(|e| UrdfError {
        file: origin.to_string(),
        kind: UrdfErrorKind::Parse(e.to_string()),
    })?;
    let taken = |n: &str| {
        robot.links.iter().any(|l| l.name == n) || robot.joints.iter().any(|j| j.name == n)
    };
    let mut link = name.to_string();
    let mut i = 2;
    while taken(&link) || taken(&format!("{link}_joint")) {
        link = format!("{name}_{i}");
        i += 1;
    }
    let pose = &last.dh_in_link;
    let c = pose.r * Vector3::from(com) + pose.p;
    let ic = six(&(pose.r * tensor(inertia) * pose.r.transpose()));
    let Some(end) = text.rfind("</robot>") else {
        return Err(UrdfError {
            file: origin.to_string(),
            kind: UrdfErrorKind::Parse("no `</robot>` closing tag".into()),
        });
    };
    let f = |v: f64| format!("{:?}", v + 0.0);
    let mut s = String::new();
    let _ = write!(
        s,
        "  <!-- the payload `dynid payload` identified, fixed to `{parent}` -->\n  <link name=\"{link}\">\n    <inertial>\n      <origin xyz=\"{} {} {}\" rpy=\"0 0 0\"/>\n      <mass value=\"{}\"/>\n      <inertia ixx=\"{}\" ixy=\"{}\" ixz=\"{}\" iyy=\"{}\" iyz=\"{}\" izz=\"{}\"/>\n    </inertial>\n  </link>\n  <joint name=\"{link}_joint\" type=\"fixed\">\n    <parent link=\"{parent}\"/>\n    <child link=\"{link}\"/>\n    <origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>\n  </joint>\n",
        f(c.x),
        f(c.y),
        f(c.z),
        f(m),
        f(ic[0]),
        f(ic[1]),
        f(ic[2]),
        f(ic[3]),
        f(ic[4]),
        f(ic[5]),
        parent = last.link,
    );
    Ok(format!("{}{s}{}", &text[..end], &text[end..]))
}
