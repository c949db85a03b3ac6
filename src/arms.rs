//! Registry of the generated arms: one module per `arms/<arm>.toml` (e.g.
//! `dynid::arms::puma560::Puma560`), written by `build.rs` and expanded by
//! `dynid_macros::arm!`.
//!
//! ```
//! let arm = dynid::arms::find("planar2").expect("planar2 is built in");
//! assert_eq!(arm.dof(), 2);
//! ```

use crate::model::Model;

include!(concat!(env!("OUT_DIR"), "/arms.rs"));

/// Every generated arm, sorted by name.
pub fn all() -> &'static [&'static dyn Model] {
    ALL
}

/// The generated arm called `name`, if there is one.
pub fn find(name: &str) -> Option<&'static dyn Model> {
    ALL.iter().copied().find(|m| m.name() == name)
}

/// Names of all generated arms.
pub fn names() -> Vec<&'static str> {
    ALL.iter().map(|m| m.name()).collect()
}

/// What `--arm` named: a generated arm, or a D-H table file for the reference dynamics.
#[derive(Debug, Clone)]
pub enum ArmSource {
    Generated(&'static dyn Model),
    Table(crate::dh::DhTable),
}

impl std::fmt::Debug for dyn Model {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Model({})", self.name())
    }
}

impl ArmSource {
    /// Degrees of freedom.
    pub fn dof(&self) -> usize {
        match self {
            ArmSource::Generated(m) => m.dof(),
            ArmSource::Table(t) => t.dof(),
        }
    }

    /// The arm's name.
    pub fn name(&self) -> &str {
        match self {
            ArmSource::Generated(m) => m.name(),
            ArmSource::Table(t) => &t.name,
        }
    }

    /// The D-H table (for a generated arm, parsed from the TOML it was generated from).
    pub fn dh_table(&self) -> Result<crate::dh::DhTable, crate::dh::DhError> {
        match self {
            ArmSource::Generated(m) => {
                crate::dh::DhTable::from_str(m.arm_toml(), &format!("arms/{}.toml", m.name()))
            }
            ArmSource::Table(t) => Ok(t.clone()),
        }
    }
}

/// `--arm` names neither a generated arm nor a readable D-H table.
#[derive(Debug, thiserror::Error)]
pub enum ArmError {
    #[error("--arm: unknown arm `{name}` — {}known arms: {}; or pass the path of a D-H table (`.toml`) or a URDF (`.urdf`)", .suggestion.map(|s| format!("did you mean `{s}`? ")).unwrap_or_default(), .known.join(", "))]
    Unknown {
        name: String,
        suggestion: Option<&'static str>,
        known: Vec<&'static str>,
    },
    #[error(transparent)]
    Table(#[from] crate::dh::DhError),
    #[error(transparent)]
    Urdf(#[from] crate::urdf::UrdfError),
}

/// Resolves `--arm`: a `.urdf` file is imported in memory (as `dynid import-urdf` does, with its
/// default options; its notes and warnings are returned by [`resolve_urdf`]); another path
/// (contains `/` or `\`, or ends in `.toml`) is loaded as a D-H table; anything else must be a
/// generated arm's name.
pub fn resolve(spec: &str) -> Result<ArmSource, ArmError> {
    if let Some(imported) = resolve_urdf(spec)? {
        return Ok(ArmSource::Table(imported.table));
    }
    let is_path = spec.contains(['/', '\\']) || spec.ends_with(".toml");
    if is_path {
        return Ok(ArmSource::Table(crate::dh::DhTable::from_path(
            std::path::Path::new(spec),
        )?));
    }
    find(spec).map(ArmSource::Generated).ok_or_else(|| {
        let known = names();
        ArmError::Unknown {
            name: spec.to_string(),
            suggestion: crate::diag::did_you_mean(spec, &known),
            known,
        }
    })
}

/// The URDF import behind `--arm ROBOT.urdf` (`None` when `spec` is not a `.urdf` path): the
/// D-H table, the URDF's own inertial parameters, the joint chain, notes and warnings.
pub fn resolve_urdf(spec: &str) -> Result<Option<crate::urdf::Imported>, ArmError> {
    let path = std::path::Path::new(spec);
    let is_urdf = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("urdf"));
    if !is_urdf {
        return Ok(None);
    }
    let opts = crate::urdf::ImportOptions::default();
    Ok(Some(crate::urdf::import_file(path, &opts)?))
}

/// The URDF behind `--arm` (`None` for a generated arm or a hand-written table): the `.urdf`
/// itself, or the `[source]` an `import-urdf` table records.
pub fn urdf_source(spec: &str) -> Result<Option<crate::urdf::roundtrip::UrdfSource>, String> {
    let path = std::path::Path::new(spec);
    let ext = path.extension().map(|e| e.to_ascii_lowercase());
    match ext.as_ref().and_then(|e| e.to_str()) {
        Some("urdf") => Ok(Some(crate::urdf::roundtrip::UrdfSource {
            path: path.to_path_buf(),
            opts: crate::urdf::ImportOptions::default(),
        })),
        Some("toml") => crate::urdf::roundtrip::UrdfSource::of_table(path),
        _ => Ok(None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--arm ROBOT.urdf` is the same chain `import-urdf` writes, and a bad one names the file.
    #[test]
    fn a_urdf_path_is_imported_in_memory() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/data/real/tiago_figaroh/tiago.urdf"
        );
        let opts = crate::urdf::ImportOptions::default();
        let direct = crate::urdf::import_file(std::path::Path::new(path), &opts).unwrap();
        let arm = resolve(path).unwrap();
        assert_eq!(arm.dof(), direct.table.dof());
        assert_eq!(arm.dh_table().unwrap(), direct.table);
        let err = resolve("no/such/robot.urdf").unwrap_err().to_string();
        assert!(err.contains("no/such/robot.urdf"), "{err}");
    }
}
