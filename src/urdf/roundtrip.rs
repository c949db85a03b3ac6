//! The identified model written back into the user's own URDF: only the moving links'
//! `<inertial>` and the chain joints' `<dynamics>` change; every other byte of the file (names,
//! order, comments, meshes, limits, gazebo and transmission tags, formatting) is kept, because
//! the new elements are spliced into the original text.
//!
//! # What goes where
//! * D-H link `k` is the URDF link its joint moves plus the bodies lumped into it (fixed below
//!   it, or on joints the import locked at 0). Its identified parameters are re-expressed in
//!   the moved link's own URDF frame (the inverse of the import's frame change: centre of mass
//!   `R·c + p`, inertia `R·I·Rᵀ` about it, `rpy = 0`).
//! * The lumped bodies keep their URDF inertials, and the moved link gets the identified body
//!   *minus* them (exact: mass, first and second moments are linear). When that difference is
//!   not a physical body (the data moved mass away from what the CAD puts there), the moved link
//!   takes the whole identified body and the lumped links' inertials are set to zero mass; the
//!   notes name them. Either way the URDF's dynamics equal the identified arm's.
//! * Bodies fixed to the base do not move; they are unchanged.
//! * `<dynamics damping friction>` of chain joint `k` become the identified viscous and Coulomb
//!   coefficients (inserted when the joint had none; left alone when neither was identified).
//!
//! ```no_run
//! # use dynid::urdf::{roundtrip, ImportOptions};
//! # let params: dynid::params::InertialParams = todo!();
//! let text = std::fs::read_to_string("robot.urdf").unwrap();
//! let out = roundtrip::rewrite(&text, "robot.urdf", &ImportOptions::default(), &params).unwrap();
//! std::fs::write("identified.urdf", out.urdf).unwrap();
//! ```

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Vector3};

use super::geom::{six, tensor};
use super::lump::{lump, Body};
use super::{import_str, ImportOptions, UrdfError, UrdfErrorKind};
use crate::params::{check_physical, InertialParams};

/// The URDF an arm came from and how it was imported: `--arm ROBOT.urdf` itself, or the
/// `[source]` table `import-urdf` writes into its D-H TOML.
#[derive(Debug, Clone)]
pub struct UrdfSource {
    pub path: PathBuf,
    pub opts: ImportOptions,
}

impl UrdfSource {
    /// The `[source]` table of a D-H TOML (`Ok(None)` without one); a relative `urdf` path is
    /// relative to the TOML's directory.
    pub fn of_table(toml_path: &Path) -> Result<Option<UrdfSource>, String> {
        let where_ = toml_path.display();
        let text = std::fs::read_to_string(toml_path).map_err(|e| format!("{where_}: {e}"))?;
        let doc: toml::Table = text.parse().map_err(|e| format!("{where_}: {e}"))?;
        let Some(src) = doc.get("source") else {
            return Ok(None);
        };
        let get = |key: &str| src.get(key).and_then(|v| v.as_str()).map(str::to_string);
        let urdf =
            get("urdf").ok_or_else(|| format!("{where_}: [source] needs `urdf = \"PATH\"`"))?;
        let gravity = match src.get("gravity").and_then(|v| v.as_array()) {
            Some(g) => {
                let v: Vec<f64> = g.iter().filter_map(|x| x.as_float()).collect();
                match v.as_slice() {
                    [x, y, z] => Some([*x, *y, *z]),
                    _ => return Err(format!("{where_}: [source] gravity must be three numbers")),
                }
            }
            None => None,
        };
        let dir = toml_path.parent().unwrap_or(Path::new("."));
        Ok(Some(UrdfSource {
            path: dir.join(urdf),
            opts: ImportOptions {
                base: get("base"),
                tip: get("tip"),
                gravity,
                name: get("name"),
            },
        }))
    }

    /// The `[source]` table for a D-H TOML written to `dir`.
    pub fn table_text(&self) -> String {
        let q = |v: &str| toml::Value::String(v.to_string()).to_string();
        let path = std::fs::canonicalize(&self.path).unwrap_or_else(|_| self.path.clone());
        let mut s = String::from(
            "\n# The URDF this table was imported from: `identify` writes its identified.urdf into it.\n[source]\n",
        );
        let _ = writeln!(s, "urdf = {}", q(&path.display().to_string()));
        for (key, v) in [
            ("base", &self.opts.base),
            ("tip", &self.opts.tip),
            ("name", &self.opts.name),
        ] {
            if let Some(v) = v {
                let _ = writeln!(s, "{key} = {}", q(v));
            }
        }
        if let Some(g) = self.opts.gravity {
            let _ = writeln!(s, "gravity = [{:?}, {:?}, {:?}]", g[0], g[1], g[2]);
        }
        s
    }

    /// [`rewrite`] of this URDF file.
    pub fn rewrite(&self, params: &InertialParams) -> Result<RoundTrip, UrdfError> {
        let origin = self.path.display().to_string();
        let text = std::fs::read_to_string(&self.path).map_err(|e| UrdfError {
            file: origin.clone(),
            kind: UrdfErrorKind::Io(e),
        })?;
        rewrite(&text, &origin, &self.opts, params)
    }
}

/// The rewritten URDF and what the rewrite had to decide.
#[derive(Debug, Clone)]
pub struct RoundTrip {
    pub urdf: String,
    pub notes: Vec<String>,
}

/// `text` (the URDF at `origin`, imported with `opts` as `--arm` did) with `params` (one link
/// per chain joint, in the import's D-H frames) as its moving links' inertials and joints'
/// `<dynamics>`.
pub fn rewrite(
    text: &str,
    origin: &str,
    opts: &ImportOptions,
    params: &InertialParams,
) -> Result<RoundTrip, UrdfError> {
    let imported = import_str(text, origin, opts)?;
    let err = |msg: String| UrdfError {
        file: origin.to_string(),
        kind: UrdfErrorKind::Internal(msg),
    };
    if params.links.len() != imported.placement.len() {
        return Err(err(format!(
            "the parameters have {} links, the URDF chain {} joints",
            params.links.len(),
            imported.placement.len()
        )));
    }
    let doc = scan(text).map_err(|m| UrdfError {
        file: origin.to_string(),
        kind: UrdfErrorKind::Parse(m),
    })?;
    let mut edits: Vec<Edit> = Vec::new();
    let mut notes = Vec::new();
    for (k, (pl, id)) in imported.placement.iter().zip(&params.links).enumerate() {
        let whole = Body {
            m: id.m,
            com: Vector3::from(id.com),
            inertia: tensor(id.inertia_com),
        };
        let others: Vec<Body> = pl.others.iter().map(|(_, b)| *b).collect();
        let (mine, zeroed) = match subtract(&whole, &lump(&others)) {
            Some(rest) if !others.is_empty() => (rest, Vec::new()),
            _ if others.is_empty() => (whole, Vec::new()),
            _ => {
                let names: Vec<&str> = pl.others.iter().map(|(n, _)| n.as_str()).collect();
                notes.push(format!(
                    "link {} (`{}`): the identified body minus the URDF inertials of {} is not physical; `{}` carries the whole identified body and their inertials are set to zero",
                    k + 1,
                    pl.link,
                    names.join(", "),
                    pl.link
                ));
                (whole, names)
            }
        };
        let in_link = Body {
            m: mine.m,
            com: pl.dh_in_link.r * mine.com + pl.dh_in_link.p,
            inertia: pl.dh_in_link.r * mine.inertia * pl.dh_in_link.r.transpose(),
        };
        edits.push(inertial_edit(&doc, text, &pl.link, &in_link).map_err(err)?);
        for name in zeroed {
            let zero = Body {
                m: 0.0,
                com: Vector3::zeros(),
                inertia: Matrix3::zeros(),
            };
            edits.push(inertial_edit(&doc, text, name, &zero).map_err(err)?);
        }
        let damping = params.effects.viscous.as_ref().map(|v| v[k]);
        let friction = params.effects.coulomb.as_ref().map(|v| v[k]);
        if damping.is_some() || friction.is_some() {
            let joint = &imported.chain[k];
            edits.push(dynamics_edit(&doc, text, joint, damping, friction).map_err(err)?);
        }
    }
    edits.sort_by_key(|e| e.start);
    let mut out = String::with_capacity(text.len() + 256);
    let mut at = 0;
    for e in &edits {
        if e.start < at {
            return Err(err(format!("overlapping edits at byte {}", e.start)));
        }
        out.push_str(&text[at..e.start]);
        out.push_str(&e.text);
        at = e.end;
    }
    out.push_str(&text[at..]);
    Ok(RoundTrip { urdf: out, notes })
}

/// `whole − part` when the rest is a physical body with mass.
fn subtract(whole: &Body, part: &Body) -> Option<Body> {
    let steiner =
        |m: f64, c: &Vector3<f64>| m * (Matrix3::identity() * c.norm_squared() - c * c.transpose());
    let m = whole.m - part.m;
    if m.is_nan() || m <= 0.0 {
        return None;
    }
    let h = whole.com * whole.m - part.com * part.m;
    let second =
        whole.inertia + steiner(whole.m, &whole.com) - part.inertia - steiner(part.m, &part.com);
    let com = h / m;
    let inertia = second - steiner(m, &com);
    check_physical(m, &six(&inertia)).ok()?;
    Some(Body { m, com, inertia })
}

/// Replace `text[start..end]` with `text`.
struct Edit {
    start: usize,
    end: usize,
    text: String,
}

/// One top-level element (`<link>`, `<joint>`, ...) of the robot: its name, where its content
/// ends (the `</link>`), its direct children's spans by tag, and its indentation.
#[derive(Debug)]
struct Top {
    tag: String,
    name: String,
    /// Where its start tag begins.
    start: usize,
    /// Where its closing tag begins (a self-closing element: where its tag ends).
    close: usize,
    self_closing: bool,
    children: Vec<(String, usize, usize)>,
}

/// The robot's top-level elements, from a small XML scanner that keeps byte offsets (the XML
/// library drops them). Comments, CDATA, processing instructions and DOCTYPE are skipped.
fn scan(text: &str) -> Result<Vec<Top>, String> {
    let b = text.as_bytes();
    let mut tops = Vec::new();
    // (tag, start) of each open element; depth 1 = robot's children.
    let mut stack: Vec<(String, usize)> = Vec::new();
    let mut i = 0;
    while let Some(off) = text[i..].find('<') {
        let start = i + off;
        let rest = &text[start..];
        let skip_to = |end: &str| -> Result<usize, String> {
            rest.find(end)
                .map(|e| start + e + end.len())
                .ok_or_else(|| format!("unterminated markup at byte {start}"))
        };
        if rest.starts_with("<!--") {
            i = skip_to("-->")?;
            continue;
        }
        if rest.starts_with("<![CDATA[") {
            i = skip_to("]]>")?;
            continue;
        }
        if rest.starts_with("<?") {
            i = skip_to("?>")?;
            continue;
        }
        if rest.starts_with("<!") {
            i = skip_to(">")?;
            continue;
        }
        // A tag: find its end outside quoted attribute values.
        let mut j = start + 1;
        let mut quote = None;
        while j < b.len() {
            match (quote, b[j]) {
                (None, b'"') | (None, b'\'') => quote = Some(b[j]),
                (Some(q), c) if c == q => quote = None,
                (None, b'>') => break,
                _ => {}
            }
            j += 1;
        }
        if j >= b.len() {
            return Err(format!("unterminated tag at byte {start}"));
        }
        let end = j + 1;
        let inner = &text[start + 1..j];
        i = end;
        if let Some(name) = inner.strip_prefix('/') {
            let name = name.trim();
            let Some((open, open_at)) = stack.pop() else {
                return Err(format!("`</{name}>` at byte {start} closes nothing"));
            };
            if open != name {
                return Err(format!("`</{name}>` at byte {start} closes `<{open}>`"));
            }
            close_element(&mut tops, stack.len(), &open, open_at, start, end);
            continue;
        }
        let self_closing = inner.ends_with('/');
        let inner = inner.trim_end_matches('/');
        let tag: String = inner
            .split(|c: char| c.is_whitespace())
            .next()
            .unwrap_or("")
            .to_string();
        if stack.len() == 1 {
            tops.push(Top {
                tag: tag.clone(),
                name: attribute(inner, "name").unwrap_or_default(),
                start,
                close: end,
                self_closing,
                children: Vec::new(),
            });
        }
        if self_closing {
            close_element(&mut tops, stack.len(), &tag, start, start, end);
        } else {
            stack.push((tag, start));
        }
    }
    Ok(tops)
}

/// Records an element that ends at `end` (its closing tag starts at `close`), at `depth`.
fn close_element(tops: &mut [Top], depth: usize, tag: &str, open: usize, close: usize, end: usize) {
    let Some(top) = tops.last_mut() else { return };
    match depth {
        1 if !top.self_closing => top.close = close,
        2 => top.children.push((tag.to_string(), open, end)),
        _ => {}
    }
}

/// The value of attribute `key` in a tag's inside (`link name="x"`).
fn attribute(inner: &str, key: &str) -> Option<String> {
    let mut rest = inner;
    while let Some(p) = rest.find(key) {
        let before_ok = p > 0 && rest.as_bytes()[p - 1].is_ascii_whitespace();
        let after = rest[p + key.len()..].trim_start();
        if before_ok {
            if let Some(v) = after.strip_prefix('=') {
                let v = v.trim_start();
                let q = v.chars().next()?;
                if q == '"' || q == '\'' {
                    let close = v[1..].find(q)?;
                    return Some(xml_unescape(&v[1..1 + close]));
                }
            }
        }
        rest = &rest[p + key.len()..];
    }
    None
}

fn xml_unescape(v: &str) -> String {
    v.replace("&quot;", "\"")
        .replace("&apos;", "'")
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&amp;", "&")
}

fn find<'a>(doc: &'a [Top], tag: &str, name: &str) -> Result<&'a Top, String> {
    doc.iter()
        .find(|t| t.tag == tag && t.name == name)
        .ok_or_else(|| format!("no <{tag} name=\"{name}\"> found by the text scanner"))
}

/// The whitespace before byte `at` on its line.
fn indent_at(text: &str, at: usize) -> &str {
    let line = text[..at].rfind('\n').map_or(0, |p| p + 1);
    let ws = &text[line..at];
    if ws.chars().all(char::is_whitespace) {
        ws
    } else {
        ""
    }
}

/// Where and how to insert a new child into `top`: the span to replace, the child's
/// indentation, and the text before and after the child.
struct Insertion {
    start: usize,
    end: usize,
    indent: String,
    before: String,
    after: String,
}

/// A new last child of `top`, on its own line before the parent's closing tag (a self-closing
/// `<link name="x"/>` is opened and closed around it).
fn insertion(text: &str, top: &Top) -> Insertion {
    let own = indent_at(text, top.start).to_string();
    let indent = top
        .children
        .first()
        .map(|c| indent_at(text, c.1).to_string())
        .filter(|i| !i.is_empty())
        .unwrap_or_else(|| format!("{own}  "));
    if top.self_closing {
        let slash = text[..top.close].rfind('/').unwrap_or(top.close);
        return Insertion {
            start: slash,
            end: top.close,
            before: format!(">\n{indent}"),
            after: format!("\n{own}</{}>", top.tag),
            indent,
        };
    }
    let closing = indent_at(text, top.close);
    if closing.is_empty() {
        return Insertion {
            start: top.close,
            end: top.close,
            before: format!("\n{indent}"),
            after: format!("\n{own}"),
            indent,
        };
    }
    let at = top.close - closing.len();
    Insertion {
        start: at,
        end: at,
        before: indent.clone(),
        after: "\n".into(),
        indent,
    }
}

fn inertial_edit(doc: &[Top], text: &str, link: &str, b: &Body) -> Result<Edit, String> {
    let top = find(doc, "link", link)?;
    let at = match top.children.iter().find(|c| c.0 == "inertial") {
        Some(&(_, start, end)) => Insertion {
            start,
            end,
            indent: indent_at(text, start).to_string(),
            before: String::new(),
            after: String::new(),
        },
        None => insertion(text, top),
    };
    let n = |v: f64| format!("{:?}", v + 0.0);
    let i = six(&b.inertia);
    let ind = &at.indent;
    let mut s = at.before.clone();
    let _ = write!(
        s,
        "<inertial>\n{ind}  <origin xyz=\"{} {} {}\" rpy=\"0 0 0\"/>\n{ind}  <mass value=\"{}\"/>\n{ind}  <inertia ixx=\"{}\" ixy=\"{}\" ixz=\"{}\" iyy=\"{}\" iyz=\"{}\" izz=\"{}\"/>\n{ind}</inertial>",
        n(b.com.x),
        n(b.com.y),
        n(b.com.z),
        n(b.m),
        n(i[0]),
        n(i[1]),
        n(i[2]),
        n(i[3]),
        n(i[4]),
        n(i[5]),
    );
    s.push_str(&at.after);
    Ok(Edit {
        start: at.start,
        end: at.end,
        text: s,
    })
}

fn dynamics_edit(
    doc: &[Top],
    text: &str,
    joint: &str,
    damping: Option<f64>,
    friction: Option<f64>,
) -> Result<Edit, String> {
    let top = find(doc, "joint", joint)?;
    let n = |v: f64| format!("{:?}", v + 0.0);
    let mut el = String::from("<dynamics");
    if let Some(d) = damping {
        let _ = write!(el, " damping=\"{}\"", n(d));
    }
    if let Some(f) = friction {
        let _ = write!(el, " friction=\"{}\"", n(f));
    }
    el.push_str("/>");
    Ok(match top.children.iter().find(|c| c.0 == "dynamics") {
        Some(&(_, start, end)) => Edit {
            start,
            end,
            text: el,
        },
        None => {
            let at = insertion(text, top);
            Edit {
                start: at.start,
                end: at.end,
                text: format!("{}{el}{}", at.before, at.after),
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scanner_finds_children_past_comments_and_quoted_brackets() {
        let t = "<?xml version=\"1.0\"?>\n<robot name=\"r\">\n  <!-- <link name=\"fake\"> -->\n  <link name=\"a>b\">\n    <inertial><mass value=\"1\"/></inertial>\n    <visual/>\n  </link>\n</robot>\n";
        let doc = scan(t).unwrap();
        assert_eq!(doc.len(), 1);
        assert_eq!(doc[0].name, "a>b");
        let tags: Vec<&str> = doc[0].children.iter().map(|c| c.0.as_str()).collect();
        assert_eq!(tags, ["inertial", "visual"]);
        let (_, s, e) = &doc[0].children[0];
        assert_eq!(&t[*s..*e], "<inertial><mass value=\"1\"/></inertial>");
        assert!(scan("<robot><link></joint></robot>").is_err());
    }
}
