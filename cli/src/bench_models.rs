//! `dynid bench-models [--arm A] [--out FILE]`: what a harness outside Rust needs to time another
//! library on exactly the models and inputs of `dynid bench` (`benches/peers/`), so that no peer
//! harness hard-codes an arm, a parameter or a seed.
//!
//! Plain text, one record per line, whitespace-separated tokens (C++ reads it with `>>`); every
//! number is printed so that it parses back to the same `f64`:
//!
//! ```text
//! dynid-bench-models 1
//! timing <target_ns> <reps> <warm_up_ns>            # dynid bench's Settings::quick()
//! arm <name> <dof> <pool>
//! gravity <gx> <gy> <gz>                             # base frame, m/s²
//! joint <i> <revolute|prismatic> <alpha> <a> <d> <theta>   # arms/<arm>.toml, modified D-H (Craig)
//! inertia <i> <XX> <XY> <XZ> <YY> <YZ> <ZZ> <MX> <MY> <MZ> <M>   # about link frame i's origin
//! sample <k> <q_1..q_n> <dq_1..dq_n> <ddq_1..ddq_n> <tau_1..tau_n>
//! end <name>
//! ```
//!
//! `inertia` is the full parameter vector `dynid bench` evaluates the kernels with; `sample k` is
//! pool sample `k` of its [`Case`] and `tau` the generated `inverse_dynamics` there.

use std::path::PathBuf;

use anyhow::Result;

use crate::write_output;
use dynid::bench::{Case, Kernel, Settings, POOL};
use dynid::dh::{DhTable, JointKind};
use dynid::model::Model;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Only this arm (default: every generated arm, as `dynid bench`).
    #[arg(long)]
    pub arm: Option<String>,
    /// Write here instead of stdout.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

struct Dump {
    table: DhTable,
    params: Vec<f64>,
    /// Per sample: q, dq, ddq, tau (each `dof` long).
    samples: Vec<[Vec<f64>; 4]>,
}

fn dump(arm: &'static dyn Model) -> Result<Dump> {
    let table = DhTable::from_str(arm.arm_toml(), &format!("arms/{}.toml", arm.name()))?;
    let case = Case::new(arm);
    let n = arm.dof();
    let pool = case.pool();
    let mut tau = vec![0.0; n];
    let samples = (0..POOL)
        .map(|k| {
            case.call_generated(Kernel::InverseDynamics, k, &mut tau);
            [
                pool.q(k).to_vec(),
                pool.dq(k).to_vec(),
                pool.ddq(k).to_vec(),
                tau.clone(),
            ]
        })
        .collect();
    Ok(Dump {
        table,
        params: case.params().to_vec(),
        samples,
    })
}

fn write_numbers(w: &mut dyn std::io::Write, xs: &[f64]) -> std::io::Result<()> {
    for x in xs {
        // `{:?}` is the shortest text that parses back to the same f64.
        write!(w, " {x:?}")?;
    }
    Ok(())
}

pub fn run(args: &Args) -> Result<()> {
    let arms = crate::bench::generated_arms(args.arm.as_deref())?;
    let dumps = arms.into_iter().map(dump).collect::<Result<Vec<_>>>()?;
    write_output(args.out.as_deref(), |w| write_dumps(w, &dumps))
}

fn write_dumps(w: &mut dyn std::io::Write, dumps: &[Dump]) -> std::io::Result<()> {
    let s = Settings::quick();
    writeln!(w, "dynid-bench-models 1")?;
    writeln!(
        w,
        "timing {} {} {}",
        s.target.as_nanos(),
        s.reps,
        s.warm_up.as_nanos()
    )?;
    for d in dumps {
        let t = &d.table;
        writeln!(w, "arm {} {} {}", t.name, t.dof(), d.samples.len())?;
        write!(w, "gravity")?;
        write_numbers(w, &t.gravity)?;
        writeln!(w)?;
        for (i, j) in t.joints.iter().enumerate() {
            let kind = match j.kind {
                JointKind::Revolute => "revolute",
                JointKind::Prismatic => "prismatic",
            };
            write!(w, "joint {} {kind}", i + 1)?;
            write_numbers(w, &[j.alpha, j.a, j.d, j.theta])?;
            writeln!(w)?;
        }
        for (i, p) in d.params.chunks(10).enumerate() {
            write!(w, "inertia {}", i + 1)?;
            write_numbers(w, p)?;
            writeln!(w)?;
        }
        for (k, sample) in d.samples.iter().enumerate() {
            write!(w, "sample {k}")?;
            for part in sample {
                write_numbers(w, part)?;
            }
            writeln!(w)?;
        }
        writeln!(w, "end {}", t.name)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bench_models_dump_parses_back_to_the_bench_inputs() {
        let arm = dynid::arms::find("planar2").expect("planar2 is built in");
        let d = dump(arm).unwrap();
        let mut text = Vec::new();
        write_dumps(&mut text, std::slice::from_ref(&d)).unwrap();
        let text = String::from_utf8(text).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "dynid-bench-models 1");
        assert!(lines[1].starts_with("timing 10000000 "), "{}", lines[1]);
        assert_eq!(lines[2], format!("arm planar2 2 {POOL}"));
        assert_eq!(lines[3], "gravity 0.0 -9.81 0.0");
        assert_eq!(lines[5], "joint 2 revolute 0.0 1.0 0.0 0.0");
        assert_eq!(lines.last(), Some(&"end planar2"));
        let case = Case::new(arm);
        let samples: Vec<&str> = lines
            .iter()
            .copied()
            .filter(|l| l.starts_with("sample "))
            .collect();
        assert_eq!(samples.len(), POOL);
        let mut tau = vec![0.0; 2];
        for k in [0, 1, POOL - 1] {
            let x: Vec<f64> = samples[k]
                .split(' ')
                .skip(2)
                .map(|t| t.parse().unwrap())
                .collect();
            case.call_generated(Kernel::InverseDynamics, k, &mut tau);
            let p = case.pool();
            let want = [p.q(k), p.dq(k), p.ddq(k), &tau[..]].concat();
            // Bit for bit: the harness checks Pinocchio against these numbers.
            assert_eq!(x, want, "sample {k}");
        }
        let inertia: Vec<f64> = lines[6]
            .split(' ')
            .skip(2)
            .map(|t| t.parse().unwrap())
            .collect();
        assert_eq!(inertia, d.params[..10]);
    }
}
