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
//! The kernel kinds (`regressor`, `base_regressor`, …) are named nowhere in this crate: they come
//! from `generated/kernels.toml`, the list the generator writes from `codegen/kernels.py`. Each
//! generated file is checked against it (every kernel present, with the listed arguments), and the
//! lane copies and the `Model` methods are expanded from it. [`kernel_methods!`] declares the
//! same methods in the trait and [`kernel_enum!`] defines `dynid::model::Kernel` from it.
//!
//! The `include_str!`s make cargo rebuild when any of these files changes. Anything wrong becomes a
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
mod manifest;

use manifest::KernelSpec;

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
/// The one function of the contract that is not a kernel (it runs once per fit: no lane copy).
const BASE_PARAMS_FN: &str = "base_params";

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

    check_fresh(
        &arm,
        &version,
        &toml,
        &generated,
        (&toml_rel, &gen_rel),
        &fix,
    )?;

    let file = syn::parse_file(&generated).map_err(|e| {
        format!("arm `{arm}`: {gen_rel} is malformed: not valid Rust ({e}) — {fix}")
    })?;
    let kernels = manifest::read(&root, &version).map_err(|e| format!("arm `{arm}`: {e}"))?;
    check_items(&arm, &gen_rel, &file.items, &kernels, &fix)?;

    let items = &file.items;
    let lane_fns = lane_fns(items, &kernels);
    let impl_fns = kernels
        .iter()
        .map(|k| impl_methods(k, defines(items, &format!("{}_fused", k.name))));
    let manifest_str = path_str(&root.join(manifest::PATH));
    let module = format_ident!("{}", arm);
    let type_name = format_ident!("{}", hash::camel_case(&arm));
    let gen_str = path_str(&gen_path);
    let toml_str = path_str(&toml_path);
    let init_str = path_str(&init_path);
    let doc =
        format!("Generated dynamics kernels of `{arm}` (from `{toml_rel}`; see `{gen_rel}`).");
    let type_doc = format!("The `{arm}` arm as a [`crate::model::Model`].");
    let helpers = module_helpers();
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
            #[doc(hidden)]
            const _KERNELS_MANIFEST: &str = include_str!(#manifest_str);
            /// The D-H table these kernels were generated from.
            pub const ARM_TOML: &str = include_str!(#toml_str);

            #(#items)*

            #(#lane_fns)*

            #helpers

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
                #(#impl_fns)*
                fn base_params(&self, p: &[f64], out: &mut [f64]) {
                    base_params(_arr(p, "p"), _arr_mut(out, "out"))
                }
            }
        }
    })
}

/// What every arm module holds beside its kernels: the op-count table, the slice-to-array checks
/// the `Model` methods call, and the lane types.
fn module_helpers() -> proc_macro2::TokenStream {
    quote! {
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
        type W = crate::pack::wide::Pack8;
    }
}

/// The generated file must record the source hash of its D-H table and generator version.
fn check_fresh(
    arm: &str,
    version: &str,
    toml: &[u8],
    generated: &str,
    (toml_rel, gen_rel): (&str, &str),
    fix: &str,
) -> Result<(), String> {
    let expected = hash::source_hash(version, toml);
    let recorded = hash::header_hash(generated).ok_or_else(|| {
        format!("arm `{arm}`: {gen_rel} is malformed: its first lines must be the `// @generated` header with `// source-hash: <hex>` — {fix}")
    })?;
    if recorded != expected {
        return Err(format!(
            "arm `{arm}`: {gen_rel} is stale: its source hash {} does not match {toml_rel} with generator {version} ({}) — {fix}",
            short(recorded),
            short(&expected)
        ));
    }
    Ok(())
}

/// Every const and fn of the contract must be there (the kernels of `generated/kernels.toml`, each
/// with the listed arguments, and `base_params`), and `NAME` must be the arm.
fn check_items(
    arm: &str,
    gen_rel: &str,
    items: &[Item],
    kernels: &[KernelSpec],
    fix: &str,
) -> Result<(), String> {
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
            Item::Fn(f) => fns.push(f),
            _ => {}
        }
    }
    let required_fns = kernels
        .iter()
        .map(|k| k.name.as_str())
        .chain([BASE_PARAMS_FN]);
    let missing: Vec<&str> = REQUIRED_CONSTS
        .iter()
        .copied()
        .filter(|c| !consts.iter().any(|x| x == c))
        .chain(required_fns.filter(|f| !fns.iter().any(|x| x.sig.ident == f)))
        .collect();
    if !missing.is_empty() {
        return Err(format!(
            "arm `{arm}`: {gen_rel} is malformed: missing {} — {fix}",
            missing.join(", ")
        ));
    }
    for f in &fns {
        let name = f.sig.ident.to_string();
        let Some(k) = kernels.iter().find(|k| k.name == name) else {
            if name == BASE_PARAMS_FN || part_of(&name, kernels).is_some() {
                continue;
            }
            return Err(format!(
                "arm `{arm}`: {gen_rel} defines `fn {name}`, which is not a kernel of {} ({}) — {fix}",
                manifest::PATH,
                kernels.iter().map(|k| k.name.as_str()).collect::<Vec<_>>().join(", ")
            ));
        };
        let got: Vec<String> = f
            .sig
            .inputs
            .iter()
            .map(|a| match a {
                syn::FnArg::Typed(t) => match &*t.pat {
                    syn::Pat::Ident(p) => p.ident.to_string(),
                    pat => quote!(#pat).to_string(),
                },
                syn::FnArg::Receiver(_) => "self".to_string(),
            })
            .collect();
        let want: Vec<&str> = k.inputs.iter().map(String::as_str).chain(["out"]).collect();
        if got != want {
            return Err(format!(
                "arm `{arm}`: {gen_rel} is malformed: `fn {name}` takes ({}), {} says ({}) — {fix}",
                got.join(", "),
                manifest::PATH,
                want.join(", ")
            ));
        }
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

/// Lane-batched copies of the kernels (not of `base_params`, which runs once per fit): of
/// `<kernel>_fused` where a kernel has a compact scalar form, and of its `<kernel>_part_*`.
fn lane_fns(items: &[Item], kernels: &[KernelSpec]) -> Vec<syn::ItemFn> {
    items
        .iter()
        .filter_map(|item| {
            let Item::Fn(f) = item else { return None };
            let name = f.sig.ident.to_string();
            match part_of(&name, kernels) {
                Some((k, Part::Fused)) => Some(lanes::lane_copy(f, &k.name)),
                Some((_, Part::Straight)) => Some(lanes::lane_copy(f, &name)),
                Some((_, Part::Scalar)) => None,
                None if kernels.iter().any(|k| k.name == name)
                    && !defines(items, &format!("{name}_fused")) =>
                {
                    Some(lanes::lane_copy(f, &name))
                }
                None => None,
            }
        })
        .collect()
}

/// Whether the generated file defines `fn name`.
fn defines(items: &[Item], name: &str) -> bool {
    items
        .iter()
        .any(|item| matches!(item, Item::Fn(f) if f.sig.ident == name))
}

/// What a helper of a kernel's compact scalar form is (`codegen/FORMAT.md`).
enum Part {
    /// `<kernel>_fused`: the straight-line kernel, the source of the lane copies.
    Fused,
    /// `<kernel>_part_<x>`: a straight-line helper, given a lane copy `<kernel>_part_<x>_lanes`.
    Straight,
    /// `<kernel>_wide`: scalar code around the parts, no lane copy.
    Scalar,
}

/// The kernel `name` is a helper of, and which kind.
fn part_of<'k>(name: &str, kernels: &'k [KernelSpec]) -> Option<(&'k KernelSpec, Part)> {
    kernels.iter().find_map(|k| {
        let rest = name.strip_prefix(k.name.as_str())?.strip_prefix('_')?;
        match rest {
            "fused" => Some((k, Part::Fused)),
            "wide" => Some((k, Part::Scalar)),
            _ if rest.starts_with("part_") => Some((k, Part::Straight)),
            _ => None,
        }
    })
}

/// The `Model` methods of one kernel for a generated arm: slices → fixed-size arrays, then the
/// generated function (and likewise for its lane copies: with and without the constant-zero
/// outputs).
fn impl_methods(k: &KernelSpec, fused: bool) -> proc_macro2::TokenStream {
    let name = format_ident!("{}", k.name);
    let straight = format_ident!("{}_straight", k.name);
    let args: Vec<Ident> = k.inputs.iter().map(|i| format_ident!("{}", i)).collect();
    let labels = &k.inputs;
    // One call site per generated function (the lane copies aside), so that the scalar method
    // is compiled as before: the straight-line form is the method itself unless a fused one exists.
    let source = if fused {
        let fused = format_ident!("{}_fused", k.name);
        quote!(#fused(#(_arr(#args, #labels),)* _arr_mut(out, "out")))
    } else {
        quote!(self.#name(#(#args,)* out))
    };
    let lane_methods = LANE_FORMS.iter().map(|&(suffix, zeros)| {
        let lanes = format_ident!("{}_lanes{}", k.name, suffix);
        let lanes8 = format_ident!("{}_lanes8{}", k.name, suffix);
        lane_methods(k, &lanes, &lanes8, zeros)
    });
    quote! {
        fn #name(&self, #(#args: &[f64],)* out: &mut [f64]) {
            #name(#(_arr(#args, #labels),)* _arr_mut(out, "out"))
        }
        fn #straight(&self, #(#args: &[f64],)* out: &mut [f64]) {
            #source
        }
        #(#lane_methods)*
    }
}

/// The lane-batched forms of every kernel: the `Model` method's suffix after `_lanes` /
/// `_lanes8`, and whether it writes the constant-zero outputs.
const LANE_FORMS: [(&str, bool); 2] = [("", true), ("_skip_zeros", false)];

/// The four- and eight-lane `Model` methods `lanes` / `lanes8` of kernel `k`: its lane copy with
/// `ZEROS = zeros`.
fn lane_methods(
    k: &KernelSpec,
    lanes: &Ident,
    lanes8: &Ident,
    zeros: bool,
) -> proc_macro2::TokenStream {
    let copy = format_ident!("{}_lanes", k.name);
    let args: Vec<Ident> = k.inputs.iter().map(|i| format_ident!("{}", i)).collect();
    let labels = &k.inputs;
    // Array lengths of the inputs (`theta`: base parameters; the rest: one value per joint) and
    // of the output, for the AVX-512 wrapper's signature.
    let lens: Vec<proc_macro2::TokenStream> = k
        .inputs
        .iter()
        .map(|i| {
            if i == "theta" {
                quote!(NB)
            } else {
                quote!(DOF)
            }
        })
        .collect();
    let out_len: syn::Expr = syn::parse_str(&k.out_len).expect("checked by manifest::read");
    // Without AVX-512, two four-lane calls into arrays on the stack, then joined: every output
    // written, as the joining writes them all (correct for both forms, and only a fallback).
    quote! {
        fn #lanes(&self, #(#args: &[P],)* out: &mut [P]) {
            #copy::<P, #zeros>(#(_arr(#args, #labels),)* _arr_mut(out, "out"))
        }
        fn #lanes8(&self, #(#args: &[W],)* out: &mut [W]) {
            #(let #args: &[W; #lens] = _arr(#args, #labels);)*
            let out: &mut [W; #out_len] = _arr_mut(out, "out");
            #[cfg(all(target_arch = "x86_64", target_feature = "fma"))]
            if crate::pack::wide::avx512() {
                #[target_feature(enable = "avx512f")]
                fn wide(#(#args: &[W; #lens],)* out: &mut [W; #out_len]) {
                    // SAFETY: compiled with AVX-512F, called only where the CPU has it.
                    unsafe {
                        #copy::<crate::pack::wide::Zmm, #zeros>(
                            #(crate::pack::wide::as_zmm(#args),)*
                            crate::pack::wide::as_zmm_mut(out),
                        )
                    }
                }
                // SAFETY: `avx512()` checked that the CPU has AVX-512F.
                return unsafe { wide(#(#args,)* out) };
            }
            // Out of line: its two output arrays on the stack would otherwise be zeroed on the
            // AVX-512 path too (seen: the eight-lane regressors store-bound, 1.05-1.3x the
            // four-lane ones).
            #[inline(never)]
            fn halves(#(#args: &[W; #lens],)* out: &mut [W; #out_len]) {
                let mut lo = [P::default(); #out_len];
                let mut hi = [P::default(); #out_len];
                #copy::<P, true>(#(&crate::pack::wide::halves(#args, 0),)* &mut lo);
                #copy::<P, true>(#(&crate::pack::wide::halves(#args, 1),)* &mut hi);
                crate::pack::wide::join_into(&lo, &hi, out);
            }
            halves(#(#args,)* out)
        }
    }
}

/// The manifest of the crate being compiled (`$CARGO_MANIFEST_DIR/generated/kernels.toml`) and
/// its path, checked against the generator version.
fn crate_manifest() -> Result<(Vec<KernelSpec>, PathBuf), String> {
    let root = PathBuf::from(
        std::env::var_os("CARGO_MANIFEST_DIR")
            .ok_or("CARGO_MANIFEST_DIR is not set (build with cargo)")?,
    );
    let init = std::fs::read_to_string(root.join("codegen/__init__.py"))
        .map_err(|e| format!("cannot read codegen/__init__.py: {e}"))?;
    let version = hash::generator_version(&init)
        .ok_or("codegen/__init__.py has no line `GENERATOR_VERSION = \"x.y.z\"` — restore it")?;
    let kernels = manifest::read(&root, &version)?;
    Ok((kernels, root.join(manifest::PATH)))
}

fn or_error(result: Result<proc_macro2::TokenStream, String>) -> TokenStream {
    match result {
        Ok(tokens) => tokens.into(),
        Err(message) => syn::Error::new(Span::call_site(), message)
            .to_compile_error()
            .into(),
    }
}

/// Declares the kernel methods of the `Model` trait (inside `trait Model { … }`): for every kernel
/// of `generated/kernels.toml`, `fn <name>(&self, <inputs>: &[f64], out: &mut [f64])` and its
/// lane-batched `fn <name>_lanes(&self, <inputs>: &[Pack], out: &mut [Pack])`.
#[proc_macro]
pub fn kernel_methods(input: TokenStream) -> TokenStream {
    if !input.is_empty() {
        return syn::Error::new(Span::call_site(), "usage: `kernel_methods!()`")
            .to_compile_error()
            .into();
    }
    or_error(crate_manifest().map(|(kernels, _)| {
        let methods = kernels.iter().map(|k| {
            let name = format_ident!("{}", k.name);
            let args: Vec<Ident> = k.inputs.iter().map(|i| format_ident!("{}", i)).collect();
            let doc = &k.doc;
            let theta_note = if k.inputs.iter().any(|i| i == "theta") {
                " (`theta` per lane; `Pack::splat` for one θ)"
            } else {
                ""
            };
            let forms = LANE_FORMS.iter().map(|&(suffix, zeros)| {
                let lanes = format_ident!("{}_lanes{}", k.name, suffix);
                let lanes8 = format_ident!("{}_lanes8{}", k.name, suffix);
                let mut lanes_doc = format!("[`Model::{}`] of `LANES` samples{theta_note}", k.name);
                let mut lanes8_doc = format!(
                    "[`Model::{}`] of `WIDE_LANES` (8) samples{theta_note}: AVX-512 where the CPU \
                     has it, else two four-lane calls (see [`crate::pack::wide`])",
                    k.name
                );
                if !zeros {
                    for doc in [&mut lanes_doc, &mut lanes8_doc] {
                        doc.push_str(
                            ", without writing the outputs that are constant zeros: `out` must \
                             hold zeros there (zero it once, then reuse it for this kernel of this \
                             model; see [`crate::pack`])",
                        );
                    }
                }
                quote! {
                    #[doc = #lanes_doc]
                    fn #lanes(&self, #(#args: &[crate::pack::Pack],)* out: &mut [crate::pack::Pack]);
                    #[doc = #lanes8_doc]
                    fn #lanes8(
                        &self,
                        #(#args: &[crate::pack::wide::Pack8],)*
                        out: &mut [crate::pack::wide::Pack8],
                    );
                }
            });
            let straight = format_ident!("{}_straight", k.name);
            let straight_doc = format!(
                "The straight-line kernel the lane copies of [`Model::{}`] are made of, which they \
                 equal bit for bit: the kernel itself, or, where it has a compact scalar form \
                 (`codegen/FORMAT.md`), the fused one (the same values to rounding).",
                k.name
            );
            quote! {
                #[doc = #doc]
                fn #name(&self, #(#args: &[f64],)* out: &mut [f64]);
                #[doc = #straight_doc]
                fn #straight(&self, #(#args: &[f64],)* out: &mut [f64]);
                #(#forms)*
            }
        });
        quote!(#(#methods)*)
    }))
}

/// Defines `pub enum Kernel` (one variant per kernel of `generated/kernels.toml`, in its order)
/// with `ALL`, `name`, `out_len` and the calls `call` / `call_lanes` / `call_lanes8` through a
/// `&dyn Model`.
#[proc_macro]
pub fn kernel_enum(input: TokenStream) -> TokenStream {
    if !input.is_empty() {
        return syn::Error::new(Span::call_site(), "usage: `kernel_enum!()`")
            .to_compile_error()
            .into();
    }
    or_error(crate_manifest().and_then(|(kernels, path)| {
        let n = kernels.len();
        let variants: Vec<Ident> = kernels
            .iter()
            .map(|k| format_ident!("{}", hash::camel_case(&k.name)))
            .collect();
        let names: Vec<&str> = kernels.iter().map(|k| k.name.as_str()).collect();
        let docs: Vec<String> = kernels
            .iter()
            .map(|k| format!("[`Model::{}`]: {}", k.name, k.doc))
            .collect();
        let out_lens = kernels
            .iter()
            .map(|k| syn::parse_str::<syn::Expr>(&k.out_len).map_err(|e| e.to_string()))
            .collect::<Result<Vec<_>, _>>()?;
        let forms = kernel_forms();
        // The parameters every call of a form takes (`ty`: its value type).
        let params = |ty: &proc_macro2::TokenStream| {
            quote!(model: &dyn Model, q: &[#ty], dq: &[#ty], ddq: &[#ty], theta: &[#ty], out: &mut [#ty])
        };
        let (kernel_calls, trait_calls) = form_calls(&variants, &forms, &params);
        let variant_calls = variant_calls(&kernels, &forms, &params)?;
        let path = path_str(&path);
        Ok(quote! {
            #[doc(hidden)]
            const _KERNELS_MANIFEST: &str = include_str!(#path);

            /// A kernel kind of the [`Model`] trait, as listed by the generator
            /// (`codegen/kernels.py` → `generated/kernels.toml`).
            #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
            pub enum Kernel {
                #(#[doc = #docs] #variants,)*
            }

            impl Kernel {
                /// Every kernel, in the generator's order (the report order).
                pub const ALL: [Kernel; #n] = [#(Kernel::#variants),*];

                /// The trait method's name (`base_regressor`), as in the JSON report.
                pub fn name(self) -> &'static str {
                    match self {
                        #(Kernel::#variants => #names,)*
                    }
                }

                /// Length of the output of an arm with `dof` joints, `np` full and `nb` base
                /// parameters.
                #[allow(non_snake_case)]
                pub fn out_len(self, dof: usize, np: usize, nb: usize) -> usize {
                    let (DOF, NP, NB) = (dof, np, nb);
                    let _ = (DOF, NP, NB);
                    match self {
                        #(Kernel::#variants => #out_lens,)*
                    }
                }

                #(#kernel_calls)*

                /// Runs `v` with this kernel kind as a type ([`KernelCall`]): a loop that calls
                /// one kernel many times chooses it once, outside the loop, instead of matching
                /// on the kind at every call as [`Kernel::call`] does.
                #[inline]
                pub fn with<V: KernelVisitor>(self, v: V) -> V::Output {
                    match self {
                        #(Kernel::#variants => v.visit::<kernel_calls::#variants>(),)*
                    }
                }
            }

            /// One kernel kind as a type: [`Kernel::call`] and [`Kernel::call_lanes`] of a kind
            /// fixed at compile time (see [`Kernel::with`]).
            pub trait KernelCall {
                /// The kind.
                const KERNEL: Kernel;
                #(#trait_calls)*
            }

            /// Work to run with a kernel kind fixed at compile time ([`Kernel::with`]).
            pub trait KernelVisitor {
                /// What the work returns.
                type Output;
                /// The work, for kernel kind `K`.
                fn visit<K: KernelCall>(self) -> Self::Output;
            }

            /// One zero-sized type per kernel kind, implementing [`KernelCall`].
            pub mod kernel_calls {
                use super::{Kernel, KernelCall, Model};
                #(
                    #[doc = #docs]
                    #[derive(Debug, Clone, Copy)]
                    pub struct #variants;

                    impl KernelCall for #variants {
                        const KERNEL: Kernel = Kernel::#variants;
                        #variant_calls
                    }
                )*
            }
        })
    }))
}

fn short(hash: &str) -> &str {
    hash.get(..12).unwrap_or(hash)
}

fn path_str(path: &Path) -> LitStr {
    LitStr::new(&path.to_string_lossy(), Span::call_site())
}

/// One form of a kernel call: `Kernel`'s method, the value type, the `Model` method's suffix, the doc.
type Form = (Ident, proc_macro2::TokenStream, String, String);

/// The forms of every kernel, one call each (scalar, then the lane-batched copies).
fn kernel_forms() -> Vec<Form> {
    let mut forms = vec![(
        format_ident!("call"),
        quote!(f64),
        String::new(),
        "Calls this kernel of `model`; inputs it does not take are ignored (`ddq`: q̈, or τ for the kernels that take τ; `theta`: base parameters).".to_string(),
    ), (
        format_ident!("call_straight"),
        quote!(f64),
        "_straight".to_string(),
        "Calls the straight-line form of this kernel of `model`, which its lane copies equal bit for bit (see `Model::<kernel>_straight`).".to_string(),
    )];
    for (suffix, zeros) in LANE_FORMS {
        let skip = if zeros {
            ""
        } else {
            ", without writing the outputs that are constant zeros (`out` must hold zeros \
             there: zero it once, then reuse it for this kernel of this model)"
        };
        forms.push((
            format_ident!("call_lanes{suffix}"),
            quote!(crate::pack::Pack),
            format!("_lanes{suffix}"),
            format!("Calls the lane-batched copy of this kernel of `model` (see [`crate::pack`]){skip}."),
        ));
        forms.push((
            format_ident!("call_lanes8{suffix}"),
            quote!(crate::pack::wide::Pack8),
            format!("_lanes8{suffix}"),
            format!("Calls the eight-lane copy of this kernel of `model` (see [`crate::pack::wide`]){skip}."),
        ));
    }
    forms
}

/// Each kernel kind's [`KernelCall`] methods: every form calls the `Model` method with the
/// kernel's own inputs.
fn variant_calls(
    kernels: &[KernelSpec],
    forms: &[Form],
    params: &dyn Fn(&proc_macro2::TokenStream) -> proc_macro2::TokenStream,
) -> Result<Vec<proc_macro2::TokenStream>, String> {
    // `Kernel::call`'s third joint-space slot is `ddq` for the kernels that take `q̈` and `τ`
    // for those that take `τ` (forward dynamics): no kernel takes both.
    let slots: Vec<Vec<Ident>> = kernels
        .iter()
        .map(|k| {
            k.inputs
                .iter()
                .map(|i| format_ident!("{}", if i == "tau" { "ddq" } else { i.as_str() }))
                .collect()
        })
        .collect();
    if let Some(k) = kernels
        .iter()
        .find(|k| k.inputs.iter().any(|i| i == "tau") && k.inputs.iter().any(|i| i == "ddq"))
    {
        return Err(format!(
            "kernel `{}` takes both `ddq` and `tau`: `Kernel::call` has one slot for them",
            k.name
        ));
    }
    Ok(kernels
        .iter()
        .zip(&slots)
        .map(|(k, args)| {
            let calls = forms.iter().map(|(call, ty, suffix, _)| {
                let method = format_ident!("{}{}", k.name, suffix);
                let params = params(ty);
                quote! {
                    #[inline(always)]
                    fn #call(#params) {
                        let _ = (q, dq, ddq, theta);
                        model.#method(#(#args,)* out)
                    }
                }
            });
            quote!(#(#calls)*)
        })
        .collect())
}

/// `Kernel`'s method of each form (a match over the kinds) and its declaration in [`KernelCall`].
fn form_calls(
    variants: &[Ident],
    forms: &[Form],
    params: &dyn Fn(&proc_macro2::TokenStream) -> proc_macro2::TokenStream,
) -> (Vec<proc_macro2::TokenStream>, Vec<proc_macro2::TokenStream>) {
    let kernel_calls = forms.iter().map(|(call, ty, _, doc)| {
        let params = params(ty);
        quote! {
            #[doc = #doc]
            #[inline]
            pub fn #call(self, #params) {
                match self {
                    #(Kernel::#variants => <kernel_calls::#variants as KernelCall>::#call(
                        model, q, dq, ddq, theta, out,
                    ),)*
                }
            }
        }
    });
    let trait_calls = forms.iter().map(|(call, ty, _, _)| {
        let doc = format!("[`Kernel::{call}`] of this kind.");
        let params = params(ty);
        quote! {
            #[doc = #doc]
            fn #call(#params);
        }
    });
    (kernel_calls.collect(), trait_calls.collect())
}
