//! Generated kernels (via the `Model` trait) against the hand-written reference, on random
//! states and random physically valid parameters, for every registered arm; planar2 against
//! the paper's Φ. Tolerances: both sides are direct floating-point evaluations of the same
//! quantities in different orders, so they agree to ~1e-13 relative; 1e-9 leaves headroom for
//! the 7-DOF arm's longer sums.

use dynid::dh::DhTable;
use dynid::model::{Kernel, Model};
use dynid::reference::RefModel;
use nalgebra::DMatrix;
use rand::Rng;

use crate::common::*;

const REL: f64 = 1e-9;

fn arm_table(m: &dyn Model) -> DhTable {
    DhTable::from_str(m.arm_toml(), m.name()).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn registry_holds_the_required_arms() {
    let names = dynid::arms::names();
    for arm in ["panda", "planar2", "puma560", "scara"] {
        assert!(names.contains(&arm), "{arm} not registered: {names:?}");
    }
    let mut sorted = names.clone();
    sorted.sort_unstable();
    assert_eq!(names, sorted, "registry is sorted by name");
    let puma = dynid::arms::find("puma560").expect("puma560");
    assert_eq!((puma.dof(), puma.np()), (6, 60));
    assert_eq!(puma.param_names().len(), 60);
    assert_eq!(puma.base_param_names().len(), puma.nb());
    assert_eq!(puma.base_param_exprs().len(), puma.nb());
    assert!(dynid::arms::find("nope").is_none());
}

#[test]
fn generated_kernels_match_the_reference() {
    let mut r = rng(2024);
    for &m in dynid::arms::all() {
        let table = arm_table(m);
        let reference = RefModel::new(&table);
        let mut ws = reference.workspace();
        let (n, np, nb) = (m.dof(), m.np(), m.nb());
        assert_eq!(n, table.dof(), "{}: DOF", m.name());
        for _ in 0..20 {
            let p = cloud_params(&random_clouds(&mut r, n));
            let (q, dq, ddq) = random_state(&mut r, n);
            let what = |k: &str| format!("{}: {k}", m.name());

            let mut tau = vec![0.0; n];
            reference.inverse_dynamics(&mut ws, &q, &dq, &ddq, &p, &mut tau);
            let mut y_ref = vec![0.0; n * np];
            reference.regressor(&mut ws, &q, &dq, &ddq, &mut y_ref);
            let mut m_ref = vec![0.0; n * n];
            reference.mass_matrix(&mut ws, &q, &p, &mut m_ref);
            let mut h_ref = vec![0.0; n];
            reference.bias(&mut ws, &q, &dq, &p, &mut h_ref);
            let mut g_ref = vec![0.0; n];
            reference.gravity(&mut ws, &q, &p, &mut g_ref);

            let mut y = vec![0.0; n * np];
            m.regressor(&q, &dq, &ddq, &mut y);
            assert_close(&y, &y_ref, REL, &what("regressor vs reference"));
            let mut theta = vec![0.0; nb];
            m.base_params(&p, &mut theta);
            let mut yb = vec![0.0; n * nb];
            m.base_regressor(&q, &dq, &ddq, &mut yb);
            assert_close(&mat_vec(&yb, &theta), &tau, REL, &what("Yb·θ vs RNEA"));
            let mut out = vec![0.0; n];
            m.inverse_dynamics(&q, &dq, &ddq, &theta, &mut out);
            assert_close(&out, &tau, REL, &what("inverse_dynamics vs RNEA"));
            let mut mm = vec![0.0; n * n];
            m.mass_matrix(&q, &theta, &mut mm);
            assert_close(&mm, &m_ref, REL, &what("mass_matrix vs CRBA"));
            m.bias(&q, &dq, &theta, &mut out);
            assert_close(&out, &h_ref, REL, &what("bias vs reference"));
            m.gravity(&q, &theta, &mut out);
            assert_close(&out, &g_ref, REL, &what("gravity vs reference"));
        }
    }
}

/// The number of base parameters equals the rank of the stacked reference regressor.
#[test]
fn base_parameter_count_is_the_regressor_rank() {
    let mut r = rng(99);
    for &m in dynid::arms::all() {
        let table = arm_table(m);
        let reference = RefModel::new(&table);
        let mut ws = reference.workspace();
        let (n, np) = (m.dof(), m.np());
        let samples = 2 * np / n + 10;
        let mut stacked = Vec::with_capacity(samples * n * np);
        let mut y = vec![0.0; n * np];
        for _ in 0..samples {
            let (mut q, dq, ddq) = random_state(&mut r, n);
            q.iter_mut().for_each(|x| *x *= r.gen_range(0.5..2.0));
            reference.regressor(&mut ws, &q, &dq, &ddq, &mut y);
            stacked.extend_from_slice(&y);
        }
        let sv = DMatrix::from_row_slice(samples * n, np, &stacked).singular_values();
        let tol = 1e-9 * sv.max();
        let rank = sv.iter().filter(|&&s| s > tol).count();
        assert_eq!(rank, m.nb(), "{}: rank of stacked Y vs NB", m.name());
    }
    assert_eq!(dynid::arms::find("puma560").map(|m| m.nb()), Some(36));
}

#[test]
fn planar2_base_regressor_is_the_paper_phi() {
    let m = dynid::arms::find("planar2").expect("planar2 registered");
    let mut r = rng(5);
    let mut yb = vec![0.0; 12];
    for _ in 0..200 {
        let (q, dq, ddq) = random_state(&mut r, 2);
        m.base_regressor(&q, &dq, &ddq, &mut yb);
        let phi = planar2_phi(&q, &dq, &ddq);
        assert_close(&yb, &phi, 1e-12, "planar2 Yb vs Φ");
        let p: Vec<f64> = (0..20).map(|_| r.gen_range(-2.0..2.0)).collect();
        let mut theta = vec![0.0; 6];
        m.base_params(&p, &mut theta);
        assert_close(&theta, &planar2_theta(&p), 1e-15, "planar2 θ");
    }
}

/// The lane-batched kernels (`dynid::pack`): every lane is bit for bit the scalar kernel on that
/// sample, for every arm and kernel, with a different θ per lane; lanes include angles beyond
/// the trigonometry's fast path so that its per-lane fallback is exercised too.
#[test]
fn lane_kernels_equal_the_scalar_kernels_bit_for_bit() {
    use dynid::pack::{gather, lane, Pack, LANES};
    let mut r = rng(77);
    for &m in dynid::arms::all() {
        let (n, np, nb) = (m.dof(), m.np(), m.nb());
        for round in 0..50 {
            // (q, dq, ddq, θ) per lane
            let samples: Vec<[Vec<f64>; 4]> = (0..LANES)
                .map(|l| {
                    let (mut q, dq, ddq) = random_state(&mut r, n);
                    if round == 0 && l == 1 {
                        q[0] = 3.0e6; // slow path in one lane only
                    }
                    let theta: Vec<f64> = (0..nb).map(|_| r.gen_range(-2.0..2.0)).collect();
                    [q, dq, ddq, theta]
                })
                .collect();
            let pack = |k: usize, len: usize| {
                let mut out = vec![Pack::default(); len];
                let rows: [&[f64]; LANES] = std::array::from_fn(|l| {
                    let s = &samples[l];
                    &s[k][..]
                });
                gather(rows, &mut out);
                out
            };
            let (q, dq, ddq, th) = (pack(0, n), pack(1, n), pack(2, n), pack(3, nb));
            let check = |name: &str, packed: &[Pack], scalar: &dyn Fn(usize, &mut [f64])| {
                let mut want = vec![0.0; packed.len()];
                let mut got = vec![0.0; packed.len()];
                for l in 0..LANES {
                    scalar(l, &mut want);
                    lane(packed, l, &mut got);
                    let same = want
                        .iter()
                        .zip(&got)
                        .all(|(a, b)| a.to_bits() == b.to_bits());
                    assert!(same, "{} {name} lane {l}: {got:?} vs {want:?}", m.name());
                }
            };
            let s = &samples;
            for kernel in Kernel::ALL {
                let mut out = vec![Pack::default(); kernel.out_len(n, np, nb)];
                kernel.call_lanes(m, &q, &dq, &ddq, &th, &mut out);
                check(kernel.name(), &out, &|l, o| {
                    kernel.call_straight(m, &s[l][0], &s[l][1], &s[l][2], &s[l][3], o)
                });
            }
        }
    }
}

/// The eight-lane kernels (`dynid::pack::wide`), in both forms — AVX-512 (where this CPU has it)
/// and two four-lane calls — are bit for bit the scalar kernel on each lane's sample, for every
/// arm and kernel, with a different θ per lane; one round puts an angle beyond the
/// trigonometry's fast path in one lane and one puts `fl(π/2)` (the exact reduction) in another.
#[test]
fn eight_lane_kernels_equal_the_scalar_kernels_bit_for_bit_in_both_forms() {
    use dynid::pack::wide::{avx512, force_halves, Pack8, WIDE_LANES};
    let mut forms = vec![false];
    if avx512() {
        forms.push(true);
    } else {
        eprintln!("no AVX-512F here (or DYNID_NO_AVX512 set): only the four-lane halves run");
    }
    let mut r = rng(78);
    for wide in forms {
        force_halves(!wide);
        assert_eq!(avx512(), wide);
        for &m in dynid::arms::all() {
            let (n, np, nb) = (m.dof(), m.np(), m.nb());
            for round in 0..30 {
                let samples: Vec<[Vec<f64>; 4]> = (0..WIDE_LANES)
                    .map(|l| {
                        let (mut q, dq, ddq) = random_state(&mut r, n);
                        match (round, l) {
                            (0, 5) => q[0] = -3.0e6,
                            (1, 2) => q[n - 1] = std::f64::consts::FRAC_PI_2,
                            _ => {}
                        }
                        let theta: Vec<f64> = (0..nb).map(|_| r.gen_range(-2.0..2.0)).collect();
                        [q, dq, ddq, theta]
                    })
                    .collect();
                let pack = |k: usize, len: usize| -> Vec<Pack8> {
                    (0..len)
                        .map(|j| Pack8::new(std::array::from_fn(|l| samples[l][k][j])))
                        .collect()
                };
                let (q, dq, ddq, th) = (pack(0, n), pack(1, n), pack(2, n), pack(3, nb));
                for kernel in Kernel::ALL {
                    let len = kernel.out_len(n, np, nb);
                    let mut out = vec![Pack8::default(); len];
                    kernel.call_lanes8(m, &q, &dq, &ddq, &th, &mut out);
                    let mut want = vec![0.0; len];
                    for (l, s) in samples.iter().enumerate() {
                        kernel.call_straight(m, &s[0], &s[1], &s[2], &s[3], &mut want);
                        let got: Vec<f64> = out.iter().map(|p| p.to_array()[l]).collect();
                        let same = want
                            .iter()
                            .zip(&got)
                            .all(|(a, b)| a.to_bits() == b.to_bits());
                        assert!(
                            same,
                            "{} {} lane {l} ({}): {got:?} vs {want:?}",
                            m.name(),
                            kernel.name(),
                            if wide { "avx512" } else { "halves" }
                        );
                    }
                }
            }
        }
    }
    force_halves(false);
}

/// The outputs a kernel writes as the constant `0.0` in `generated/<arm>.rs` (the oracle of the
/// skip-zeros forms: read from the source text, not from the macro that turns those stores into
/// skipped ones).
fn constant_zero_outputs(arm: &str, kernel: &str) -> Vec<usize> {
    let path = format!(
        "{}/generated/{arm}.rs",
        concat!(env!("CARGO_MANIFEST_DIR"), "/..")
    );
    let src = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    // The lane copies are made of `<kernel>_fused` where the kernel has a compact scalar form.
    let start = src
        .find(&format!("\npub fn {kernel}_fused("))
        .or_else(|| src.find(&format!("\npub fn {kernel}(")))
        .unwrap_or_else(|| panic!("{path}: no `pub fn {kernel}`"));
    let body = &src[start..];
    let body = &body[..body.find("\n}\n").expect("the function's closing brace")];
    body.lines()
        .filter_map(|l| {
            let k = l.trim().strip_prefix("out[")?.strip_suffix("] = 0.0;")?;
            Some(k.parse().expect("an output index"))
        })
        .collect()
}

/// The skip-zeros forms (`Kernel::call_lanes_skip_zeros`, `call_lanes8_skip_zeros`) write every
/// output but the generated source's constant zeros, each lane bit for bit the scalar kernel, and
/// leave exactly those zeros as the buffer held them — four lanes, eight (AVX-512 where this CPU
/// has it); the eight-lane fallback (two four-lane calls) writes them all, as documented. The
/// regressors have such zeros (so the test is not vacuous there).
#[test]
fn skip_zeros_forms_leave_exactly_the_constant_zeros_unwritten() {
    use dynid::pack::wide::{avx512, force_halves, Pack8, WIDE_LANES};
    use dynid::pack::{Pack, LANES};
    const SENTINEL: f64 = 12345.678;
    let mut r = rng(79);
    let mut checked_zeros = 0;
    for &m in dynid::arms::all() {
        let (n, np, nb) = (m.dof(), m.np(), m.nb());
        let samples: Vec<[Vec<f64>; 4]> = (0..WIDE_LANES)
            .map(|_| {
                let (q, dq, ddq) = random_state(&mut r, n);
                let theta: Vec<f64> = (0..nb).map(|_| r.gen_range(-2.0..2.0)).collect();
                [q, dq, ddq, theta]
            })
            .collect();
        let pack8 = |k: usize, len: usize| -> Vec<Pack8> {
            (0..len)
                .map(|j| Pack8::new(std::array::from_fn(|l| samples[l][k][j])))
                .collect()
        };
        let (q8, dq8, ddq8, th8) = (pack8(0, n), pack8(1, n), pack8(2, n), pack8(3, nb));
        let lo = |v: &[Pack8]| -> Vec<Pack> {
            v.iter()
                .map(|p| Pack::new(std::array::from_fn(|l| p.to_array()[l])))
                .collect()
        };
        let (q4, dq4, ddq4, th4) = (lo(&q8), lo(&dq8), lo(&ddq8), lo(&th8));
        for kernel in Kernel::ALL {
            let len = kernel.out_len(n, np, nb);
            let zeros = constant_zero_outputs(m.name(), kernel.name());
            checked_zeros += zeros.len();
            let mut want = vec![vec![0.0; len]; WIDE_LANES];
            for (l, s) in samples.iter().enumerate() {
                kernel.call_straight(m, &s[0], &s[1], &s[2], &s[3], &mut want[l]);
            }
            // (width, form, whether the zeros are left unwritten, lanes of each output)
            let mut runs: Vec<(usize, &str, bool, Vec<Vec<f64>>)> = Vec::new();
            let mut out4 = vec![Pack::splat(SENTINEL); len];
            kernel.call_lanes_skip_zeros(m, &q4, &dq4, &ddq4, &th4, &mut out4);
            let lanes4 = out4.iter().map(|p| p.to_array().to_vec()).collect();
            runs.push((LANES, "four lanes", true, lanes4));
            let mut forms = vec![false];
            if avx512() {
                forms.push(true);
            }
            for wide in forms {
                force_halves(!wide);
                let mut out8 = vec![Pack8::splat(SENTINEL); len];
                kernel.call_lanes8_skip_zeros(m, &q8, &dq8, &ddq8, &th8, &mut out8);
                let lanes8 = out8.iter().map(|p| p.to_array().to_vec()).collect();
                runs.push((
                    WIDE_LANES,
                    if wide { "avx512" } else { "halves" },
                    wide,
                    lanes8,
                ));
            }
            force_halves(false);
            for (width, form, skips, got) in runs {
                for (k, lanes) in got.iter().enumerate() {
                    for (l, &g) in lanes.iter().enumerate().take(width) {
                        let w = want[l][k];
                        let ok = if skips && zeros.contains(&k) {
                            g == SENTINEL
                        } else {
                            g.to_bits() == w.to_bits()
                        };
                        assert!(
                            ok,
                            "{} {} ({form}) output {k} lane {l}: {g} (scalar {w}; constant zero: {})",
                            m.name(),
                            kernel.name(),
                            zeros.contains(&k)
                        );
                    }
                }
            }
        }
    }
    assert!(
        checked_zeros > 100,
        "only {checked_zeros} constant zeros found in the sources"
    );
}

/// `Kernel::with` hands its visitor the very kind it was called on (the bench's timing loops
/// choose the kernel this way, once per loop), whose `KernelCall` type — through which
/// `Kernel::call` dispatches too — gives that kind's outputs, its lane-batched copy the same bit
/// for bit, for every arm.
#[test]
fn kernel_with_visits_the_kind_it_was_called_on() {
    use dynid::model::{KernelCall, KernelVisitor};
    use dynid::pack::{lane, Pack};
    struct Probe<'a> {
        m: &'a dyn Model,
        s: &'a [Vec<f64>; 4],
        len: usize,
    }
    impl KernelVisitor for Probe<'_> {
        type Output = (Kernel, Vec<f64>, Vec<Pack>);
        fn visit<K: KernelCall>(self) -> Self::Output {
            let s = self.s;
            let mut out = vec![0.0; self.len];
            K::call(self.m, &s[0], &s[1], &s[2], &s[3], &mut out);
            let p: Vec<Vec<Pack>> = s
                .iter()
                .map(|v| v.iter().map(|&x| Pack::splat(x)).collect())
                .collect();
            let mut lanes = vec![Pack::default(); self.len];
            K::call_lanes(self.m, &p[0], &p[1], &p[2], &p[3], &mut lanes);
            (K::KERNEL, out, lanes)
        }
    }
    let mut r = rng(91);
    for &m in dynid::arms::all() {
        let (q, dq, ddq) = random_state(&mut r, m.dof());
        let theta: Vec<f64> = (0..m.nb()).map(|_| r.gen_range(-2.0..2.0)).collect();
        let s = [q, dq, ddq, theta];
        for kernel in Kernel::ALL {
            let len = kernel.out_len(m.dof(), m.np(), m.nb());
            let (kind, got, lanes) = kernel.with(Probe { m, s: &s, len });
            assert_eq!(kind, kernel, "{}", m.name());
            let mut want = vec![0.0; len];
            kernel.call(m, &s[0], &s[1], &s[2], &s[3], &mut want);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&got), bits(&want), "{} {}", m.name(), kernel.name());
            let mut first = vec![0.0; len];
            lane(&lanes, 0, &mut first);
            kernel.call_straight(m, &s[0], &s[1], &s[2], &s[3], &mut want);
            assert_eq!(
                bits(&first),
                bits(&want),
                "{} {} lanes",
                m.name(),
                kernel.name()
            );
        }
    }
}
