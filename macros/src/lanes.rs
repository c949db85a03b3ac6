//! The lane-batched copy of a generated kernel (see `dynid::pack`): the same body with `f64`
//! replaced by `crate::pack::Pack`, every float literal `c` by `Pack::splat(c)` and
//! `crate::trig::sin_cos` by `crate::pack::sin_cos`. The function becomes `<name>_lanes`.

use quote::{format_ident, quote};
use syn::visit_mut::{self, VisitMut};
use syn::{parse_quote, Expr, ExprLit, ExprPath, ItemFn, Lit, Type};

struct ToLanes;

impl VisitMut for ToLanes {
    fn visit_type_mut(&mut self, ty: &mut Type) {
        if let Type::Path(p) = ty {
            if p.qself.is_none() && p.path.is_ident("f64") {
                *ty = parse_quote!(crate::pack::Pack);
                return;
            }
        }
        visit_mut::visit_type_mut(self, ty);
    }

    fn visit_expr_mut(&mut self, expr: &mut Expr) {
        match expr {
            Expr::Lit(ExprLit {
                lit: Lit::Float(f), ..
            }) => {
                let f = f.clone();
                *expr = parse_quote!(crate::pack::Pack::splat(#f));
            }
            Expr::Path(ExprPath { path, .. })
                if quote!(#path).to_string().replace(' ', "") == "crate::trig::sin_cos" =>
            {
                *path = parse_quote!(crate::pack::sin_cos);
            }
            _ => visit_mut::visit_expr_mut(self, expr),
        }
    }
}

/// `fn name(..f64..)` → `fn name_lanes(..Pack..)`.
pub fn lane_copy(f: &ItemFn) -> ItemFn {
    let mut g = f.clone();
    g.sig.ident = format_ident!("{}_lanes", f.sig.ident);
    ToLanes.visit_item_fn_mut(&mut g);
    g.attrs
        .push(parse_quote!(#[doc = "Lane-batched copy (see `crate::pack`)."]));
    g
}
