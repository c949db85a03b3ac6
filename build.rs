//! Keeps `generated/` in step with `arms/` and writes the arm registry.
//!
//! For each `arms/<arm>.toml` (the stem must be a lowercase Rust identifier equal to its `name`
//! key) the source hash (TOML bytes + generator version) is compared with the `// source-hash:`
//! header of `generated/<arm>.rs`. Stale or missing files are regenerated with one
//! `python3 -m codegen <arm>...` run (the generator writes atomically, only changed content).
//! Then `$OUT_DIR/arms.rs` gets one `dynid_macros::arm!(<arm>);` per arm plus `ALL`, which
//! `src/arms.rs` includes. Adding an arm = adding its TOML and running `cargo build`.
//! It also names the target's vector forms for the kernels' sine/cosine (`vector_cfgs`).
//!
//! Environment: `DYNID_PYTHON` overrides the interpreter (default: `.venv/bin/python` when
//! `scripts/test.sh` has made it, else `python3`); `DYNID_ZMM_TRIG` the sine/cosine form.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

#[path = "macros/src/hash.rs"]
mod hash;

struct Arm {
    name: String,
    toml: PathBuf,
    generated: PathBuf,
}

/// The target's vector forms, as cfgs. `cfg(dynid_avx)`: x86-64 with AVX2 and FMA, what the
/// four-lane and SSE-pair sine/cosine forms need (one name for the condition `trig` and `pack`
/// test in many places). `cfg(dynid_zmm_trig)`, only on such a target with AVX-512F:
/// `trig::sin_cos8` as one eight-lane evaluation, for a build whose target is this machine, an
/// AMD CPU (its 512-bit instructions do not slow the scalar code beside them; an Intel core's
/// do — see `trig::sin_cos8`). The values are the same either way. `DYNID_ZMM_TRIG=1` or `0`
/// overrides the CPU check.
fn vector_cfgs() {
    println!("cargo::rustc-check-cfg=cfg(dynid_avx)");
    println!("cargo::rustc-check-cfg=cfg(dynid_zmm_trig)");
    println!("cargo:rerun-if-env-changed=DYNID_ZMM_TRIG");
    let features = std::env::var("CARGO_CFG_TARGET_FEATURE").unwrap_or_default();
    let has = |feature: &str| features.split(',').any(|f| f == feature);
    let x86_64 = std::env::var("CARGO_CFG_TARGET_ARCH").is_ok_and(|a| a == "x86_64");
    let avx = x86_64 && has("avx2") && has("fma");
    if avx {
        println!("cargo:rustc-cfg=dynid_avx");
    }
    let native = std::env::var("TARGET").ok() == std::env::var("HOST").ok();
    let wanted = match std::env::var("DYNID_ZMM_TRIG").as_deref() {
        Ok("1") => true,
        Ok("0") => false,
        _ => native && host_is_amd(),
    };
    if avx && has("avx512f") && wanted {
        println!("cargo:rustc-cfg=dynid_zmm_trig");
    }
}

/// Whether the CPU running the build is an AMD one (CPUID leaf 0's vendor string).
#[cfg(target_arch = "x86_64")]
fn host_is_amd() -> bool {
    // SAFETY: CPUID is part of x86-64.
    #[allow(unused_unsafe)]
    let r = unsafe { std::arch::x86_64::__cpuid(0) };
    let vendor: Vec<u8> = [r.ebx, r.edx, r.ecx]
        .iter()
        .flat_map(|w| w.to_le_bytes())
        .collect();
    vendor == b"AuthenticAMD"
}

#[cfg(not(target_arch = "x86_64"))]
fn host_is_amd() -> bool {
    false
}

fn main() {
    if let Err(message) = run() {
        // A build-script error is printed by cargo with our stderr; keep it to the point.
        eprintln!("\nerror: {message}\n");
        std::process::exit(1);
    }
}

fn run() -> Result<(), String> {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").map_err(|e| e.to_string())?);
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").map_err(|e| e.to_string())?);
    let arms_dir = manifest.join("arms");
    let codegen = manifest.join("codegen");

    vector_cfgs();
    println!("cargo:rerun-if-changed=arms");
    println!("cargo:rerun-if-env-changed=DYNID_PYTHON");
    // Individual generator files, not the directory: pytest and __pycache__ would retrigger.
    let mut py_files: Vec<PathBuf> = read_dir_sorted(&codegen)?
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "py"))
        .collect();
    py_files.push(codegen.join("requirements.txt"));
    for f in &py_files {
        println!("cargo:rerun-if-changed={}", f.display());
    }

    let arms = discover(&arms_dir, &manifest)?;
    let version = std::fs::read_to_string(codegen.join("__init__.py"))
        .ok()
        .and_then(|s| hash::generator_version(&s));

    let mut registered = Vec::new();
    match &version {
        Some(version) => {
            let stale: Vec<&Arm> = arms.iter().filter(|a| !is_fresh(a, version)).collect();
            if !stale.is_empty() {
                regenerate(&manifest, &stale)?;
                for arm in &stale {
                    if !is_fresh(arm, version) {
                        return Err(format!(
                            "the generator ran but generated/{}.rs is still out of date with arms/{}.toml — run `python3 -m codegen {}` and read its output",
                            arm.name, arm.name, arm.name
                        ));
                    }
                }
            }
            registered.extend(arms.iter().map(|a| a.name.clone()));
        }
        None => {
            // No generator (yet): register what exists and say what is skipped.
            for arm in &arms {
                if arm.generated.exists() {
                    registered.push(arm.name.clone());
                } else {
                    println!(
                        "cargo:warning=arm `{}` skipped: generated/{}.rs is missing and codegen/__init__.py (GENERATOR_VERSION) is not there to regenerate it",
                        arm.name, arm.name
                    );
                }
            }
        }
    }
    write_registry(&out_dir.join("arms.rs"), &registered)
}

fn read_dir_sorted(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(format!("cannot list {}: {e}", dir.display())),
    };
    let mut paths: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    paths.sort();
    Ok(paths)
}

/// Every `arms/*.toml`, sorted, with its stem checked against the `name` key.
fn discover(arms_dir: &Path, manifest: &Path) -> Result<Vec<Arm>, String> {
    let mut arms = Vec::new();
    for path in read_dir_sorted(arms_dir)? {
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let shown = format!("arms/{stem}.toml");
        if !hash::is_valid_arm_name(&stem) {
            return Err(format!(
                "{shown}: the file name must be a lowercase Rust identifier (letters, digits, `_`; not a keyword), e.g. `arms/my_arm.toml` — rename the file and set `name` to match"
            ));
        }
        let text =
            std::fs::read_to_string(&path).map_err(|e| format!("{shown}: cannot read: {e}"))?;
        let value: toml::Table = text.parse().map_err(|e: toml::de::Error| {
            format!("{shown}: not valid TOML: {} — fix the syntax", e.message())
        })?;
        match value.get("name").and_then(|v| v.as_str()) {
            Some(name) if name == stem => {}
            Some(name) => {
                return Err(format!(
                    "{shown}: `name = \"{name}\"` differs from the file name — set `name = \"{stem}\"` or rename the file to arms/{name}.toml"
                ))
            }
            None => return Err(format!("{shown}: missing `name` — add `name = \"{stem}\"`")),
        }
        arms.push(Arm {
            generated: manifest.join("generated").join(format!("{stem}.rs")),
            toml: path,
            name: stem,
        });
    }
    Ok(arms)
}

fn is_fresh(arm: &Arm, version: &str) -> bool {
    let (Ok(toml), Ok(generated)) = (
        std::fs::read(&arm.toml),
        std::fs::read_to_string(&arm.generated),
    ) else {
        return false;
    };
    hash::header_hash(&generated) == Some(hash::source_hash(version, &toml).as_str())
}

fn regenerate(manifest: &Path, stale: &[&Arm]) -> Result<(), String> {
    let python = python(manifest);
    let names: Vec<&str> = stale.iter().map(|a| a.name.as_str()).collect();
    let install = "run `scripts/test.sh` once (it sets up `.venv/` with the pinned generator), or install Python ≥ 3.10 and `pip install -r codegen/requirements.txt`";
    // Not a cargo:warning: cargo replays cached warnings on later no-op builds, which would
    // claim a regeneration that is not happening. Visible with `cargo build -vv`.
    eprintln!(
        "regenerating {} (arms/*.toml changed or generated/ out of date)",
        names.join(", ")
    );
    let output = Command::new(&python)
        .arg("-m")
        .arg("codegen")
        .args(&names)
        .current_dir(manifest)
        .env("PYTHONDONTWRITEBYTECODE", "1")
        .output()
        .map_err(|e| {
            format!(
                "generated/{}.rs must be regenerated but `{python}` could not be run ({e}) — {install} (or set DYNID_PYTHON to your interpreter)",
                names.join(".rs, generated/")
            )
        })?;
    if output.status.success() {
        return Ok(());
    }
    let stderr = String::from_utf8_lossy(&output.stderr);
    let stdout = String::from_utf8_lossy(&output.stdout);
    let hint = if let Some(module) = missing_module(&stderr) {
        format!("the Python package `{module}` is missing — {install}")
    } else {
        "fix the error above (usually in the arm's TOML), then run `cargo build` again".to_string()
    };
    Err(format!(
        "`{python} -m codegen {}` failed ({}):\n{}{}\n{hint}",
        names.join(" "),
        output.status,
        stdout.trim_end(),
        stderr.trim_end()
    ))
}

/// The interpreter that runs the generator: `DYNID_PYTHON`, else the project's `.venv/` (made by
/// `scripts/test.sh`) when it exists, else `python3` on the `PATH`.
fn python(manifest: &Path) -> String {
    if let Ok(p) = std::env::var("DYNID_PYTHON") {
        return p;
    }
    let venv = manifest.join(".venv/bin/python");
    if venv.exists() {
        return venv.display().to_string();
    }
    "python3".to_string()
}

fn missing_module(stderr: &str) -> Option<&str> {
    let rest = stderr.split("No module named ").nth(1)?;
    let name = rest.trim_start_matches(['\'', '"']);
    Some(name.split(['\'', '"', '\n']).next().unwrap_or(name))
}

fn write_registry(path: &Path, names: &[String]) -> Result<(), String> {
    let mut names = names.to_vec();
    names.sort();
    let mut s = String::from("// @generated by build.rs: one module per arms/*.toml.\n");
    for n in &names {
        let _ = writeln!(s, "dynid_macros::arm!({n});");
    }
    s.push_str("\n/// Every generated arm, sorted by name.\npub static ALL: &[&dyn crate::model::Model] = &[");
    for n in &names {
        let _ = write!(s, "&{n}::{}, ", hash::camel_case(n));
    }
    s.push_str("];\n");
    // Only write on change, so an unchanged registry does not trigger recompilation.
    if std::fs::read_to_string(path).ok().as_deref() == Some(s.as_str()) {
        return Ok(());
    }
    std::fs::write(path, s).map_err(|e| format!("cannot write {}: {e}", path.display()))
}
