//! The lane-batched copy of a generated kernel (see `dynid::pack`): the same body, generic over
//! the lane type `L: crate::pack::Lane`, with `f64` replaced by `L`, every float literal `c` by
//! `L::splat(c)` and `crate::trig::sin_cos{,2,3,4,8}` and `crate::trig::mul_add` by the `L` methods of
//! those names. The function becomes
//! `<name>_lanes::<L>`, always inlined (into the `Model` methods that pick `L`, and into the
//! AVX-512 wrappers, which must compile it with their target features). Its `const ZEROS: bool`
//! says whether it writes the constant-zero outputs (`false`: the `_skip_zeros` forms).

use quote::{format_ident, quote};
use syn::visit_mut::{self, VisitMut};
use syn::{parse_quote, Expr, ExprLit, ExprPath, ItemFn, Lit, Type};

struct ToLanes;

/// The functions the kernels call (trigonometry and fused multiply-adds), each mapped to the
/// `crate::pack::Lane` method of its name.
const CALLS: [&str; 6] = [
    "crate::trig::sin_cos",
    "crate::trig::sin_cos2",
    "crate::trig::sin_cos3",
    "crate::trig::sin_cos4",
    "crate::trig::sin_cos8",
    "crate::trig::mul_add",
];

impl VisitMut for ToLanes {
    fn visit_type_mut(&mut self, ty: &mut Type) {
        if let Type::Path(p) = ty {
            if p.qself.is_none() && p.path.is_ident("f64") {
                *ty = parse_quote!(L);
                return;
            }
        }
        visit_mut::visit_type_mut(self, ty);
    }

    fn visit_expr_mut(&mut self, expr: &mut Expr) {
        if let Some(place) = zero_store(expr) {
            *expr = parse_quote!(if ZEROS {
                crate::pack::store_zero::<L>(&mut #place)
            });
            return;
        }
        match expr {
            Expr::Lit(ExprLit {
                lit: Lit::Float(f), ..
            }) => {
                let f = f.clone();
                *expr = parse_quote!(<L as crate::pack::Lane>::splat(#f));
            }
            Expr::Path(ExprPath { path, .. })
                if CALLS.contains(&quote!(#path).to_string().replace(' ', "").as_str()) =>
            {
                let name = path.segments.last().expect("a path").ident.clone();
                *expr = parse_quote!(<L as crate::pack::Lane>::#name);
            }
            _ => visit_mut::visit_expr_mut(self, expr),
        }
    }
}

/// `out[k] = 0.0` (a constant zero output): its place, `out[k]`. Such stores become
/// `crate::pack::store_zero::<L>` in the lane copies, so that the lane type decides how a zero is
/// stored (the eight-lane one keeps LLVM from merging runs of them into a `memset` call: up to
/// 131 of the SCARA regressor's 160 outputs are zeros), and only when the copy's `ZEROS` is
/// true: the `_skip_zeros` forms leave those outputs as they are (the regressors' zeros cost
/// the eight-lane forms about one cycle each, a 64-byte store: about a third of the Panda
/// regressor's time).
fn zero_store(expr: &Expr) -> Option<Expr> {
    let Expr::Assign(a) = expr else { return None };
    let Expr::Lit(ExprLit {
        lit: Lit::Float(f), ..
    }) = &*a.right
    else {
        return None;
    };
    let is_out = matches!(&*a.left, Expr::Index(i) if matches!(&*i.expr, Expr::Path(p) if p.path.is_ident("out")));
    (is_out && f.base10_parse::<f64>().ok() == Some(0.0) && !f.base10_digits().starts_with('-'))
        .then(|| (*a.left).clone())
}

/// `fn name(..f64..)` → `fn <kernel>_lanes<L: Lane, const ZEROS: bool>(..L..)` (`ZEROS`: whether
/// the constant-zero outputs are written), `kernel` being `name`, or the kernel whose
/// `<kernel>_fused` `name` is.
pub fn lane_copy(f: &ItemFn, kernel: &str) -> ItemFn {
    let mut g = f.clone();
    g.sig.ident = format_ident!("{}_lanes", kernel);
    ToLanes.visit_item_fn_mut(&mut g);
    g.sig.generics = parse_quote!(<L: crate::pack::Lane, const ZEROS: bool>);
    g.attrs.retain(|a| !a.path().is_ident("inline"));
    g.attrs.push(parse_quote!(#[inline(always)]));
    g.attrs
        .push(parse_quote!(#[doc = "Lane-batched copy (see `crate::pack`)."]));
    g
}
