//! `dynid arms [ARM] [--json]`.

use anyhow::Result;
use serde::Serialize;

use crate::{write_output, InputError};
use dynid::model::Model;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Show only this arm.
    pub arm: Option<String>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct ArmInfo<'a> {
    name: &'a str,
    dof: usize,
    np: usize,
    nb: usize,
    base_params: Vec<BaseParam<'a>>,
    op_counts: Vec<OpCountInfo<'a>>,
}

#[derive(Serialize)]
struct BaseParam<'a> {
    name: &'a str,
    expr: &'a str,
}

#[derive(Serialize)]
struct OpCountInfo<'a> {
    kernel: &'a str,
    mul: u32,
    add: u32,
}

fn info(m: &'static dyn Model) -> ArmInfo<'static> {
    ArmInfo {
        name: m.name(),
        dof: m.dof(),
        np: m.np(),
        nb: m.nb(),
        base_params: m
            .base_param_names()
            .iter()
            .zip(m.base_param_exprs())
            .map(|(&name, &expr)| BaseParam { name, expr })
            .collect(),
        op_counts: m
            .op_counts()
            .iter()
            .map(|o| OpCountInfo {
                kernel: o.kernel,
                mul: o.mul,
                add: o.add,
            })
            .collect(),
    }
}

pub fn run(args: &Args) -> Result<()> {
    let arms: Vec<&'static dyn Model> = match &args.arm {
        Some(name) => match dynid::arms::resolve(name)? {
            dynid::arms::ArmSource::Generated(m) => vec![m],
            dynid::arms::ArmSource::Table(t) => {
                return Err(InputError(format!(
                    "{name}: `dynid arms` lists generated arms — copy the table to arms/{}.toml and run `cargo build` to generate it",
                    t.name
                ))
                .into())
            }
        },
        None => dynid::arms::all().to_vec(),
    };
    let infos: Vec<ArmInfo> = arms.into_iter().map(info).collect();
    write_output(None, |w| {
        if args.json {
            serde_json::to_writer_pretty(&mut *w, &infos)?;
            return writeln!(w);
        }
        writeln!(w, "{:<12} {:>4} {:>4} {:>4}", "ARM", "DOF", "NP", "NB")?;
        for a in &infos {
            writeln!(w, "{:<12} {:>4} {:>4} {:>4}", a.name, a.dof, a.np, a.nb)?;
        }
        for a in &infos {
            writeln!(
                w,
                "\n{}: {} base parameters (θ = base_params(p))",
                a.name, a.nb
            )?;
            let width = a
                .base_params
                .iter()
                .map(|b| b.name.len())
                .max()
                .unwrap_or(0);
            for (i, b) in a.base_params.iter().enumerate() {
                writeln!(w, "  θ{:<3} {:<width$} = {}", i + 1, b.name, b.expr)?;
            }
        }
        Ok(())
    })
}
