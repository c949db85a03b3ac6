//! `dynid_macros::arm!(planar2)` embeds `generated/planar2.rs` as typed Rust items.
//!
//! Thin by design (sqlx-macros style): it reads `arms/<arm>.toml`, `codegen/__init__.py`
//! (for `GENERATOR_VERSION`) and `generated/<arm>.rs` under the crate root, checks that the
//! generated file is fresh (its `// source-hash:` header equals the hash of the TOML and the
//! generator version) and has every item of the contract (`codegen/FORMAT.md`), and emits
//!
//! ```ignore
//! pub mod planar2 {
//!     /* the generated items */
//!     pub const ARM_TOML: &str = include_str!(".../arms/planar2.toml");
//!     pub struct Planar2;
//!     impl crate::model::Model for Planar2 { /* slices → fixed-size arrays */ }
//! }
//! ```
//!
//! The `include_str!`s make cargo rebuild when either file changes. Anything wrong becomes a
//! `compile_error!` naming the arm, the file and the fix.
//!
//! `arm!(name, root = "dir")` reads from another root (for tests): an absolute path, or one
//! relative to `$DYNID_MACROS_BASE` if set (trybuild sets no useful manifest dir), else to
//! `$CARGO_MANIFEST_DIR`.

use std::path::{Path, PathBuf};

use proc_macro::TokenStream;
use proc_macro2::Span;
use quote::{format_ident, quote};
use syn::parse::{Parse, ParseStream};
use syn::{Ident, Item, LitStr, Token};

mod hash;
mod lanes;

struct ArmArgs {
    name: Ident,
    root: Option<LitStr>,
}

impl Parse for ArmArgs {
    fn parse(input: ParseStream) -> syn::Result<Self> {
        let name: Ident = input.parse()?;
        let mut root = None;
        if input.parse::<Option<Token![,]>>()?.is_some() && !input.is_empty() {
            let key: Ident = input.parse()?;
            if key != "root" {
                return Err(syn::Error::new(key.span(), "expected `root = \"dir\"`"));
            }
            input.parse::<Token![=]>()?;
            root = Some(input.parse()?);
            input.parse::<Option<Token![,]>>()?;
        }
        if !input.is_empty() {
            return Err(input.error("usage: `arm!(name)` or `arm!(name, root = \"dir\")`"));
        }
        Ok(ArmArgs { name, root })
    }
}

/// Embeds the generated kernels of one arm; see the crate docs.
#[proc_macro]
pub fn arm(input: TokenStream) -> TokenStream {
    let args = syn::parse_macro_input!(input as ArmArgs);
    match expand(&args) {
        Ok(tokens) => tokens.into(),
        Err(message) => syn::Error::new(args.name.span(), message)
            .to_compile_error()
            .into(),
    }
}

const REQUIRED_CONSTS: [&str; 11] = [
    "NAME",
    "DOF",
    "NP",
    "NB",
    "GENERATOR_VERSION",
    "SOURCE_HASH",
    "PARAM_NAMES",
    "BASE_PARAM_NAMES",
    "BASE_PARAM_EXPRS",
    "BASE_MAP",
    "OP_COUNTS",
];
const REQUIRED_FNS: [&str; 7] = [
    "regressor",
    "base_regressor",
    "mass_matrix",
    "bias",
    "gravity",
    "inverse_dynamics",
    "base_params",
];

/// The kernels that also get a lane-batched copy (`<name>_lanes`).
const KERNELS: [&str; 6] = [
    "regressor",
    "base_regressor",
    "mass_matrix",
    "bias",
    "gravity",
    "inverse_dynamics",
];

fn root_dir(args: &ArmArgs) -> Result<PathBuf, String> {
    let manifest = std::env::var_os("CARGO_MANIFEST_DIR")
        .ok_or("CARGO_MANIFEST_DIR is not set (build with cargo)")?;
    let Some(root) = &args.root else {
        return Ok(PathBuf::from(manifest));
    };
    let root = PathBuf::from(root.value());
    if root.is_absolute() {
        return Ok(root);
    }
    let base = std::env::var_os("DYNID_MACROS_BASE").unwrap_or(manifest);
    Ok(Path::new(&base).join(root))
}

fn expand(args: &ArmArgs) -> Result<proc_macro2::TokenStream, String> {
    let arm = args.name.to_string();
    if !hash::is_valid_arm_name(&arm) {
        return Err(format!(
            "arm `{arm}`: arm names are lowercase Rust identifiers (e.g. `puma560`, `my_arm`)"
        ));
    }
    let root = root_dir(args)?;
    let toml_rel = format!("arms/{arm}.toml");
    let gen_rel = format!("generated/{arm}.rs");
    let fix = format!("run `cargo build` (build.rs regenerates it) or `python -m codegen {arm}`");

    let toml_path = root.join(&toml_rel);
    let toml = std::fs::read(&toml_path)
        .map_err(|e| format!("arm `{arm}`: cannot read {toml_rel}: {e} — add the D-H table {toml_rel} (one TOML per arm)"))?;
    let init_path = root.join("codegen/__init__.py");
    let init = std::fs::read_to_string(&init_path)
        .map_err(|e| format!("arm `{arm}`: cannot read codegen/__init__.py: {e} — the generator package is needed for GENERATOR_VERSION"))?;
    let version = hash::generator_version(&init).ok_or_else(|| {
        format!("arm `{arm}`: codegen/__init__.py has no line `GENERATOR_VERSION = \"x.y.z\"` — restore it")
    })?;
    let gen_path = root.join(&gen_rel);
    // build.rs does not watch generated/ (its own writes would retrigger it), so after a
    // deletion `cargo build` alone does not regenerate: say what does.
    let generated = std::fs::read_to_string(&gen_path).map_err(|e| {
        format!("arm `{arm}`: cannot read {gen_rel}: {e} — run `python -m codegen {arm}` (or `touch {toml_rel}` and `cargo build`)")
    })?;

    let expected = hash::source_hash(&version, &toml);
    let recorded = hash::header_hash(&generated).ok_or_else(|| {
        format!("arm `{arm}`: {gen_rel} is malformed: its first lines must be the `// @generated` header with `// source-hash: <hex>` — {fix}")
    })?;
    if recorded != expected {
        return Err(format!(
            "arm `{arm}`: {gen_rel} is stale: its source hash {} does not match {toml_rel} with generator {version} ({}) — {fix}",
            short(recorded),
            short(&expected)
        ));
    }

    let file = syn::parse_file(&generated).map_err(|e| {
        format!("arm `{arm}`: {gen_rel} is malformed: not valid Rust ({e}) — {fix}")
    })?;
    check_items(&arm, &gen_rel, &file.items, &fix)?;

    let items = &file.items;
    // Lane-batched copies of the kernels (not of `base_params`, which runs once per fit).
    let lane_fns: Vec<syn::ItemFn> = items
        .iter()
        .filter_map(|item| match item {
            Item::Fn(f) if KERNELS.contains(&f.sig.ident.to_string().as_str()) => {
                Some(lanes::lane_copy(f))
            }
            _ => None,
        })
        .collect();
    let module = format_ident!("{}", arm);
    let type_name = format_ident!("{}", hash::camel_case(&arm));
    let gen_str = path_str(&gen_path);
    let toml_str = path_str(&toml_path);
    let init_str = path_str(&init_path);
    let doc =
        format!("Generated dynamics kernels of `{arm}` (from `{toml_rel}`; see `{gen_rel}`).");
    let type_doc = format!("The `{arm}` arm as a [`crate::model::Model`].");
    Ok(quote! {
        #[doc = #doc]
        #[allow(
            unused,
            missing_docs,
            non_snake_case,
            non_upper_case_globals,
            clippy::all,
            clippy::pedantic,
            clippy::nursery,
            clippy::excessive_precision,
            clippy::approx_constant,
            clippy::too_many_lines,
            clippy::unreadable_literal,
            clippy::many_single_char_names
        )]
        pub mod #module {
            // Tracked by cargo: editing either file recompiles this module.
            #[doc(hidden)]
            const _GENERATED_SOURCE: &str = include_str!(#gen_str);
            #[doc(hidden)]
            const _GENERATOR_INIT: &str = include_str!(#init_str);
            /// The D-H table these kernels were generated from.
            pub const ARM_TOML: &str = include_str!(#toml_str);

            #(#items)*

            #(#lane_fns)*

            const _OP_COUNTS: [crate::model::OpCount; OP_COUNTS.len()] = {
                let mut out = [crate::model::OpCount { kernel: "", mul: 0, add: 0 }; OP_COUNTS.len()];
                let mut i = 0;
                while i < OP_COUNTS.len() {
                    out[i] = crate::model::OpCount { kernel: OP_COUNTS[i].0, mul: OP_COUNTS[i].1, add: OP_COUNTS[i].2 };
                    i += 1;
                }
                out
            };

            #[cold]
            #[inline(never)]
            fn _bad_len(what: &str, len: usize, expected: usize) -> ! {
                panic!("{}: `{}` has length {}, expected {}", NAME, what, len, expected)
            }

            #[inline(always)]
            fn _arr<'a, T, const N: usize>(s: &'a [T], what: &str) -> &'a [T; N] {
                match <&[T; N]>::try_from(s) {
                    Ok(a) => a,
                    Err(_) => _bad_len(what, s.len(), N),
                }
            }

            #[inline(always)]
            fn _arr_mut<'a, T, const N: usize>(s: &'a mut [T], what: &str) -> &'a mut [T; N] {
                let len = s.len();
                match <&mut [T; N]>::try_from(s) {
                    Ok(a) => a,
                    Err(_) => _bad_len(what, len, N),
                }
            }

            type P = crate::pack::Pack;

            #[doc = #type_doc]
            #[derive(Debug, Clone, Copy, Default)]
            pub struct #type_name;

            impl crate::model::Model for #type_name {
                fn name(&self) -> &'static str { NAME }
                fn dof(&self) -> usize { DOF }
                fn np(&self) -> usize { NP }
                fn nb(&self) -> usize { NB }
                fn param_names(&self) -> &'static [&'static str] { &PARAM_NAMES }
                fn base_param_names(&self) -> &'static [&'static str] { &BASE_PARAM_NAMES }
                fn base_param_exprs(&self) -> &'static [&'static str] { &BASE_PARAM_EXPRS }
                fn arm_toml(&self) -> &'static str { ARM_TOML }
                fn op_counts(&self) -> &'static [crate::model::OpCount] { &_OP_COUNTS }
                fn regressor(&self, q: &[f64], dq: &[f64], ddq: &[f64], out: &mut [f64]) {
                    regressor(_arr(q, "q"), _arr(dq, "dq"), _arr(ddq, "ddq"), _arr_mut(out, "out"))
                }
                fn base_regressor(&self, q: &[f64], dq: &[f64], ddq: &[f64], out: &mut [f64]) {
                    base_regressor(_arr(q, "q"), _arr(dq, "dq"), _arr(ddq, "ddq"), _arr_mut(out, "out"))
                }
                fn mass_matrix(&self, q: &[f64], theta: &[f64], out: &mut [f64]) {
                    mass_matrix(_arr(q, "q"), _arr(theta, "theta"), _arr_mut(out, "out"))
                }
                fn bias(&self, q: &[f64], dq: &[f64], theta: &[f64], out: &mut [f64]) {
                    bias(_arr(q, "q"), _arr(dq, "dq"), _arr(theta, "theta"), _arr_mut(out, "out"))
                }
                fn gravity(&self, q: &[f64], theta: &[f64], out: &mut [f64]) {
                    gravity(_arr(q, "q"), _arr(theta, "theta"), _arr_mut(out, "out"))
                }
                fn inverse_dynamics(&self, q: &[f64], dq: &[f64], ddq: &[f64], theta: &[f64], out: &mut [f64]) {
                    inverse_dynamics(_arr(q, "q"), _arr(dq, "dq"), _arr(ddq, "ddq"), _arr(theta, "theta"), _arr_mut(out, "out"))
                }
                fn base_params(&self, p: &[f64], out: &mut [f64]) {
                    base_params(_arr(p, "p"), _arr_mut(out, "out"))
                }
                fn regressor_lanes(&self, q: &[P], dq: &[P], ddq: &[P], out: &mut [P]) {
                    regressor_lanes(_arr(q, "q"), _arr(dq, "dq"), _arr(ddq, "ddq"), _arr_mut(out, "out"))
                }
                fn base_regressor_lanes(&self, q: &[P], dq: &[P], ddq: &[P], out: &mut [P]) {
                    base_regressor_lanes(_arr(q, "q"), _arr(dq, "dq"), _arr(ddq, "ddq"), _arr_mut(out, "out"))
                }
                fn mass_matrix_lanes(&self, q: &[P], theta: &[P], out: &mut [P]) {
                    mass_matrix_lanes(_arr(q, "q"), _arr(theta, "theta"), _arr_mut(out, "out"))
                }
                fn bias_lanes(&self, q: &[P], dq: &[P], theta: &[P], out: &mut [P]) {
                    bias_lanes(_arr(q, "q"), _arr(dq, "dq"), _arr(theta, "theta"), _arr_mut(out, "out"))
                }
                fn gravity_lanes(&self, q: &[P], theta: &[P], out: &mut [P]) {
                    gravity_lanes(_arr(q, "q"), _arr(theta, "theta"), _arr_mut(out, "out"))
                }
                fn inverse_dynamics_lanes(&self, q: &[P], dq: &[P], ddq: &[P], theta: &[P], out: &mut [P]) {
                    inverse_dynamics_lanes(_arr(q, "q"), _arr(dq, "dq"), _arr(ddq, "ddq"), _arr(theta, "theta"), _arr_mut(out, "out"))
                }
            }
        }
    })
}

/// Every const and fn of the contract must be there, and `NAME` must be the arm.
fn check_items(arm: &str, gen_rel: &str, items: &[Item], fix: &str) -> Result<(), String> {
    let mut consts = Vec::new();
    let mut fns = Vec::new();
    let mut name_value = None;
    for item in items {
        match item {
            Item::Const(c) => {
                if c.ident == "NAME" {
                    if let syn::Expr::Lit(syn::ExprLit {
                        lit: syn::Lit::Str(s),
                        ..
                    }) = &*c.expr
                    {
                        name_value = Some(s.value());
                    }
                }
                consts.push(c.ident.to_string());
            }
            Item::Fn(f) => fns.push(f.sig.ident.to_string()),
            _ => {}
        }
    }
    let missing: Vec<&str> = REQUIRED_CONSTS
        .iter()
        .filter(|c| !consts.iter().any(|x| x == *c))
        .chain(REQUIRED_FNS.iter().filter(|f| !fns.iter().any(|x| x == *f)))
        .copied()
        .collect();
    if !missing.is_empty() {
        return Err(format!(
            "arm `{arm}`: {gen_rel} is malformed: missing {} — {fix}",
            missing.join(", ")
        ));
    }
    match name_value {
        Some(n) if n == arm => Ok(()),
        Some(n) => Err(format!(
            "arm `{arm}`: {gen_rel} is malformed: `NAME` is \"{n}\", expected \"{arm}\" — {fix}"
        )),
        None => Err(format!(
            "arm `{arm}`: {gen_rel} is malformed: `NAME` is not a string literal — {fix}"
        )),
    }
}

fn short(hash: &str) -> &str {
    hash.get(..12).unwrap_or(hash)
}

fn path_str(path: &Path) -> LitStr {
    LitStr::new(&path.to_string_lossy(), Span::call_site())
}
