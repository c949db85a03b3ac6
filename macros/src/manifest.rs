//! `generated/kernels.toml`: the one list of kernel kinds, written by the generator from
//! `codegen/kernels.py` (see `codegen/FORMAT.md`). Everything in the crate that names the kernels
//! one by one — the check of each generated file, the lane copies, the `Model` trait's kernel
//! methods and their implementations, `dynid::model::Kernel` — is expanded from it.

use std::path::Path;

/// Rust names of the kernel inputs (`q`, `dq`, `ddq`: joint values, `tau`: joint forces,
/// `theta`: base parameters).
pub const INPUTS: [&str; 5] = ["q", "dq", "ddq", "tau", "theta"];

/// Where the manifest lives under the crate root.
pub const PATH: &str = "generated/kernels.toml";

/// One kernel kind.
pub struct KernelSpec {
    /// Function and trait-method name, e.g. `base_regressor`.
    pub name: String,
    /// Arguments before `out`, each one of [`INPUTS`].
    pub inputs: Vec<String>,
    /// Length of `out` as a Rust expression in `DOF`, `NP`, `NB`.
    pub out_len: String,
    /// Doc line of the trait method.
    pub doc: String,
}

/// Reads and checks the manifest under `root`; `version` is the generator's `GENERATOR_VERSION`.
pub fn read(root: &Path, version: &str) -> Result<Vec<KernelSpec>, String> {
    let fix = "run `python -m codegen --manifest-only` (or `python -m codegen`)";
    let text = std::fs::read_to_string(root.join(PATH))
        .map_err(|e| format!("cannot read {PATH}: {e} — {fix}"))?;
    let bad = |what: String| format!("{PATH} is malformed: {what} — {fix}");
    let table: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| bad(e.message().to_string()))?;
    let written = table
        .get("generator_version")
        .and_then(|v| v.as_str())
        .ok_or_else(|| bad("no `generator_version`".into()))?;
    if written != version {
        return Err(format!(
            "{PATH} is stale: written by generator {written}, codegen/__init__.py is {version} — {fix}"
        ));
    }
    let kernels = table
        .get("kernel")
        .and_then(|v| v.as_array())
        .ok_or_else(|| bad("no `[[kernel]]` tables".into()))?;
    let mut out: Vec<KernelSpec> = Vec::new();
    for (i, k) in kernels.iter().enumerate() {
        let field = |key: &str| {
            k.get(key)
                .and_then(|v| v.as_str())
                .map(str::to_string)
                .ok_or_else(|| bad(format!("kernel {}: no string `{key}`", i + 1)))
        };
        let name = field("name")?;
        let inputs: Vec<String> = k
            .get("inputs")
            .and_then(|v| v.as_array())
            .and_then(|a| a.iter().map(|x| x.as_str().map(str::to_string)).collect())
            .ok_or_else(|| {
                bad(format!(
                    "kernel `{name}`: `inputs` is not a list of strings"
                ))
            })?;
        if let Some(x) = inputs.iter().find(|x| !INPUTS.contains(&x.as_str())) {
            return Err(bad(format!(
                "kernel `{name}`: unknown input `{x}` (one of {})",
                INPUTS.join(", ")
            )));
        }
        if syn::parse_str::<syn::Ident>(&name).is_err()
            || name == "base_params"
            || out.iter().any(|o| o.name == name)
        {
            return Err(bad(format!(
                "kernel name `{name}` is not a new Rust identifier"
            )));
        }
        let out_len = field("out_len")?;
        if syn::parse_str::<syn::Expr>(&out_len).is_err() {
            return Err(bad(format!(
                "kernel `{name}`: out_len `{out_len}` is not a Rust expression"
            )));
        }
        let doc = field("doc")?;
        out.push(KernelSpec {
            name,
            inputs,
            out_len,
            doc,
        });
    }
    if out.is_empty() {
        return Err(bad("no kernels".into()));
    }
    Ok(out)
}
