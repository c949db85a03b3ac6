//! Criterion benchmark of the physically consistent identification (`cargo bench --bench
//! physical`).
//!
//! - `physical/seven_link_solve`: one [`ConsistentProblem::solve`] of a 7-DOF-sized problem from
//!   `dynid::physical::synth::seven_link` — 70 standard parameters, 49 base parameters with the
//!   regrouping of a revolute chain, `N` from a 2000-row random regressor whose columns span three
//!   decades, 21 effects (14 non-negative, 7 bounded in `[0, 0.5]`), noise that pushes links out
//!   of the physical set. Setup (the synthetic problem) is outside the timing.
//! - `physical/seven_link_ellipsoids`: the same with a margin and a bounding ellipsoid per link.
//!
//! The requirement is ≤ 2 s per solve on 2 cores.

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use dynid::physical::synth::seven_link;
use dynid::physical::{ConsistentProblem, Ellipsoid, Margin};

fn solve(pb: &ConsistentProblem) {
    let fit = pb.solve().expect("the synthetic problem solves");
    assert!(fit.links.iter().all(|l| l.consistent));
    black_box(fit);
}

fn physical(c: &mut Criterion) {
    let syn = seven_link(2000, 3.0, 5);
    let mut g = c.benchmark_group("physical");
    g.bench_function("seven_link_solve", |b| {
        b.iter(|| solve(black_box(&syn.problem)))
    });
    let mut with_shapes = syn.problem.clone();
    with_shapes.margin = Some(Margin {
        mass: 0.01,
        length: 0.001,
    });
    with_shapes.ellipsoids = (0..7)
        .map(|l| {
            let m = syn.params[10 * l + 9];
            let centre = [0, 1, 2].map(|k| syn.params[10 * l + 6 + k] / m);
            Some(Ellipsoid {
                centre,
                semi_axes: [0.6; 3],
            })
        })
        .collect();
    g.bench_function("seven_link_ellipsoids", |b| {
        b.iter(|| solve(black_box(&with_shapes)))
    });
    g.finish();
}

fn config() -> Criterion {
    Criterion::default()
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3))
        .sample_size(30)
}

criterion_group! { name = benches; config = config(); targets = physical }
criterion_main!(benches);
