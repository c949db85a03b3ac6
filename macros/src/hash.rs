//! Freshness of generated kernels: the source hash of an arm and the header that records it.
//!
//! Shared by the proc-macro and by the `dynid` build script (`#[path]`-included there), so the
//! two can never disagree about what "stale" means. The generator (`codegen/`) computes the
//! same hash in Python; `codegen/FORMAT.md` is the contract.
#![allow(dead_code)] // each includer uses a subset

use sha2::{Digest, Sha256};

/// `sha256(b"dynid-codegen <version>\n" + toml_bytes)`, lowercase hex.
pub fn source_hash(version: &str, toml: &[u8]) -> String {
    let mut h = Sha256::new();
    h.update(format!("dynid-codegen {version}\n").as_bytes());
    h.update(toml);
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// The value of the line `GENERATOR_VERSION = "x.y.z"` (a type annotation is allowed) in the
/// generator's `__init__.py`.
pub fn generator_version(init_py: &str) -> Option<String> {
    init_py.lines().find_map(|line| {
        let rest = line.trim_start().strip_prefix("GENERATOR_VERSION")?;
        let value = rest.split_once('=')?.1.trim();
        let quote = value.chars().next().filter(|c| *c == '"' || *c == '\'')?;
        let inner = &value[1..];
        let end = inner.find(quote)?;
        Some(inner[..end].to_string())
    })
}

/// The hash recorded in a generated file's header (`// source-hash: <hex>` among the leading
/// comment lines), if the header has the `// @generated` marker and such a line.
pub fn header_hash(generated: &str) -> Option<&str> {
    let mut lines = generated.lines();
    if !lines.next()?.starts_with("// @generated") {
        return None;
    }
    lines
        .take_while(|l| l.starts_with("//"))
        .find_map(|l| l.strip_prefix("// source-hash:"))
        .map(str::trim)
}

/// Arm names are lowercase Rust identifiers (they become module names).
pub fn is_valid_arm_name(name: &str) -> bool {
    const KEYWORDS: [&str; 51] = [
        "as", "break", "const", "continue", "crate", "else", "enum", "extern", "false", "fn",
        "for", "if", "impl", "in", "let", "loop", "match", "mod", "move", "mut", "pub", "ref",
        "return", "self", "static", "struct", "super", "trait", "true", "type", "unsafe", "use",
        "where", "while", "async", "await", "dyn", "abstract", "become", "box", "do", "final",
        "macro", "override", "priv", "typeof", "unsized", "virtual", "yield", "try", "gen",
    ];
    let mut chars = name.chars();
    let Some(first) = chars.next() else {
        return false;
    };
    (first.is_ascii_lowercase() || first == '_')
        && name != "_"
        && chars.all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
        && !KEYWORDS.contains(&name)
}

/// `puma560` → `Puma560`, `my_arm` → `MyArm`.
pub fn camel_case(name: &str) -> String {
    name.split('_')
        .filter(|s| !s.is_empty())
        .map(|s| {
            let mut c = s.chars();
            c.next()
                .map(|f| f.to_ascii_uppercase().to_string() + c.as_str())
                .unwrap_or_default()
        })
        .collect()
}
