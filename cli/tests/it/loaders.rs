//! Loaders: a corpus of malformed inputs under `tests/corpus/{dh,params,csv}/`, each with the
//! exact message it must produce in a sibling `<file>.err` (regenerate with `DYNID_BLESS=1`
//! and review the diff); valid files with real-world quirks under `tests/corpus/valid/`;
//! independent checks of the parameter conversion; round trips; "never panics" properties.

use std::path::{Path, PathBuf};

use dynid::data::Trajectory;
use dynid::dh::DhTable;
use dynid::params::{check_physical, InertialParams, NonPhysical, ParamsOptions};
use proptest::prelude::*;

use crate::common::*;

const CORPUS_DOF: usize = 2;

fn corpus(kind: &str) -> Vec<PathBuf> {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .join("tests/corpus")
        .join(kind);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("dir entry").path())
        .filter(|p| !p.to_string_lossy().ends_with(".err"))
        .collect();
    files.sort();
    files
}

/// The message for one corpus file, with the path as the user would type it from the root.
fn message(kind: &str, path: &Path) -> String {
    let shown = format!(
        "tests/corpus/{kind}/{}",
        path.file_name().expect("file name").to_string_lossy()
    );
    let opts = ParamsOptions::default();
    let result = match kind {
        "dh" => {
            let text = std::fs::read_to_string(path).expect("utf-8 corpus file");
            DhTable::from_str(&text, &shown)
                .map(|_| ())
                .map_err(|e| e.to_string())
        }
        "params" => {
            let text = std::fs::read_to_string(path).expect("utf-8 corpus file");
            InertialParams::from_str(&text, &shown, CORPUS_DOF, &opts)
                .map(|_| ())
                .map_err(|e| e.to_string())
        }
        "csv" => {
            let bytes = std::fs::read(path).expect("corpus file");
            Trajectory::from_reader(bytes.as_slice(), &shown, Some(CORPUS_DOF))
                .map(|_| ())
                .map_err(|e| e.to_string())
        }
        _ => unreachable!(),
    };
    match result {
        Ok(()) => panic!("{shown}: accepted, but it is in the malformed corpus"),
        Err(msg) => msg,
    }
}

fn check_corpus(kind: &str) {
    let bless = std::env::var_os("DYNID_BLESS").is_some();
    let files = corpus(kind);
    assert!(files.len() >= 10, "corpus {kind} is too small");
    let mut failures = Vec::new();
    for path in files {
        let msg = message(kind, &path);
        let err_path = PathBuf::from(format!("{}.err", path.display()));
        if bless {
            std::fs::write(&err_path, format!("{msg}\n")).expect("write .err");
            continue;
        }
        let expected = std::fs::read_to_string(&err_path).unwrap_or_else(|_| {
            panic!(
                "{}: missing; run with DYNID_BLESS=1 and review",
                err_path.display()
            )
        });
        if expected.trim_end() != msg {
            failures.push(format!(
                "{}\n  expected: {}\n  actual:   {msg}",
                path.display(),
                expected.trim_end()
            ));
        }
        // Every message names the file and says how to fix it.
        assert!(msg.starts_with("tests/corpus/"), "{msg}");
        assert!(msg.contains(" — "), "no fix given: {msg}");
    }
    assert!(
        failures.is_empty(),
        "messages changed:\n{}",
        failures.join("\n")
    );
}

#[test]
fn malformed_dh_tables_have_exact_messages() {
    check_corpus("dh");
}

#[test]
fn malformed_params_have_exact_messages() {
    check_corpus("params");
}

#[test]
fn malformed_csv_have_exact_messages() {
    check_corpus("csv");
}

#[test]
fn csv_quirks_of_real_exports_are_accepted() {
    for path in corpus("valid") {
        let traj = Trajectory::from_path(&path, Some(2)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(traj.t, [0.0, 0.01, 0.02], "{}", path.display());
        assert_eq!(traj.q, [0.5, 0.2, 0.6, 0.2, 0.7, 0.2], "{}", path.display());
        assert!(traj.dq.is_some() && traj.ddq.is_some() && traj.tau.is_none());
    }
}

#[test]
fn csv_dof_is_inferred_when_not_given() {
    let traj = Trajectory::from_reader(
        "t,q1,q2,q3,tau1,tau2,tau3\n0,1,2,3,4,5,6\n".as_bytes(),
        "x.csv",
        None,
    )
    .unwrap();
    assert_eq!((traj.dof, traj.tau_at(0)), (3, Some(&[4.0, 5.0, 6.0][..])));
}

/// Long files are parsed a batch of rows at a time (in parallel): every row still arrives in
/// order, and the first error in the file is the one reported, with its line, wherever it is.
#[test]
fn long_csv_files_read_whole_and_report_their_first_error() {
    let rows = 30_001;
    let mut text = String::from("t,q1,tau1\n");
    for k in 0..rows {
        text += &format!("{},{},{}\n", k as f64 * 1e-3, (k as f64).sin(), k);
    }
    let traj = Trajectory::from_reader(text.as_bytes(), "long.csv", Some(1)).unwrap();
    assert_eq!(traj.t.len(), rows);
    assert!(traj
        .q
        .iter()
        .enumerate()
        .all(|(k, &q)| q == (k as f64).sin()));
    assert!((0..rows).all(|k| traj.tau_at(k) == Some(&[k as f64][..])));

    // Line l holds sample l - 2 (the header is line 1).
    let with = |edits: &[(usize, &str)]| {
        let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
        for &(line, row) in edits {
            lines[line - 1] = row.to_string();
        }
        let err = Trajectory::from_reader(lines.join("\n").as_bytes(), "long.csv", Some(1));
        err.unwrap_err().to_string()
    };
    // A bad cell after the first batch, and a later time step back: the cell is first.
    let e = with(&[(20_000, "19.998,x,1"), (25_000, "0,0,0")]);
    assert!(
        e.starts_with("long.csv:20000") && e.contains(": q1:"),
        "{e}"
    );
    // A time step back across a batch boundary, before a bad cell in the same later batch.
    let e = with(&[(8194, "0.0001,0,0"), (8200, "0.5,0,y")]);
    assert!(
        e.starts_with("long.csv:8194") && e.contains(": t: t = 0.0001 does not increase"),
        "{e}"
    );
    // In one row, the time going back is reported before a bad cell (as the reader meets them).
    let e = with(&[(17_000, "0.0001,z,0")]);
    assert!(
        e.starts_with("long.csv:17000") && e.contains(": t: t = 0.0001 does not increase"),
        "{e}"
    );
    // A row with a cell missing, in the last (partial) batch.
    let e = with(&[(rows + 1, "30.0,1")]);
    assert!(e.starts_with(&format!("long.csv:{}", rows + 1)), "{e}");
}

#[test]
fn torque_needs_derivative_columns() {
    let traj = Trajectory::from_reader("t,q1\n0,1\n".as_bytes(), "x.csv", Some(1)).unwrap();
    let err = traj
        .require(true, true, false, "inverse dynamics")
        .unwrap_err()
        .to_string();
    assert_eq!(
        err,
        "x.csv: no `dq` columns, needed for inverse dynamics — add them (expected columns t, q1..q1, then optionally dq1..dq1, ddq1..ddq1, and tau1..tau1)"
    );
}

#[test]
fn every_arm_table_loads() {
    let tables = all_tables();
    let names: Vec<&str> = tables.iter().map(|t| t.name.as_str()).collect();
    for arm in ["planar2", "puma560", "panda", "scara"] {
        assert!(names.contains(&arm), "{arm} missing from arms/");
    }
}

/// `full_vector` against the definition: a link made of point masses, described by its COM and
/// its inertia about the COM, must give the point cloud's moments about the link origin.
#[test]
fn params_match_point_mass_definitions() {
    let mut r = rng(11);
    let clouds = random_clouds(&mut r, 3);
    let expected = cloud_params(&clouds);
    let mut text = String::new();
    for cloud in &clouds {
        let m: f64 = cloud.iter().map(|(m, _)| m).sum();
        let c: Vec<f64> = (0..3)
            .map(|k| cloud.iter().map(|(mi, ri)| mi * ri[k]).sum::<f64>() / m)
            .collect();
        let rel: Vec<(f64, [f64; 3])> = cloud
            .iter()
            .map(|&(mi, ri)| (mi, [ri[0] - c[0], ri[1] - c[1], ri[2] - c[2]]))
            .collect();
        let ic = &cloud_params(&[rel])[..6];
        text += &format!(
            "[[link]]\nm = {m:?}\ncom = [{:?}, {:?}, {:?}]\ninertia_com = [{:?}, {:?}, {:?}, {:?}, {:?}, {:?}]\n\n",
            c[0], c[1], c[2], ic[0], ic[1], ic[2], ic[3], ic[4], ic[5]
        );
    }
    let params = InertialParams::from_str(&text, "cloud.toml", 3, &ParamsOptions::default())
        .unwrap_or_else(|e| panic!("{e}"));
    assert_close(
        &params.full_vector(),
        &expected,
        1e-13,
        "params vs point masses",
    );

    // The same links given about the origin round-trip to the same vector.
    let mut text = String::new();
    for l in &params.links {
        let o = l.inertia_origin;
        text += &format!(
            "[[link]]\nm = {:?}\ncom = [{:?}, {:?}, {:?}]\ninertia_origin = [{:?}, {:?}, {:?}, {:?}, {:?}, {:?}]\n\n",
            l.m, l.com[0], l.com[1], l.com[2], o[0], o[1], o[2], o[3], o[4], o[5]
        );
    }
    let again =
        InertialParams::from_str(&text, "origin.toml", 3, &ParamsOptions::default()).unwrap();
    assert_close(
        &again.full_vector(),
        &expected,
        1e-13,
        "inertia_origin round trip",
    );
}

#[test]
fn massless_links_and_nonphysical_warnings() {
    let text = "[[link]]\nm = 0.0\n\n[[link]]\nm = 1.0\ncom = [0.0, 0.0, 0.0]\ninertia_com = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\n";
    let p = InertialParams::from_str(text, "x.toml", 2, &ParamsOptions::default()).unwrap();
    assert_eq!(p.full_vector()[..10], [0.0; 10]);
    assert!(p.warnings.is_empty());

    // PUMA-style link 1 (m = 0, Izz only) is accepted with a warning when allowed.
    let puma = "[[link]]\nm = 0.0\ninertia_com = [0.0, 0.0, 0.0, 0.0, 0.0, 0.35]\n";
    assert!(InertialParams::from_str(puma, "x.toml", 1, &ParamsOptions::default()).is_err());
    let allowed = InertialParams::from_str(
        puma,
        "x.toml",
        1,
        &ParamsOptions {
            allow_nonphysical: true,
        },
    )
    .unwrap();
    assert_eq!(allowed.warnings.len(), 1);
    assert_eq!(allowed.full_vector()[5], 0.35);
    let in_file = format!("allow_nonphysical = true\n{puma}");
    assert_eq!(
        InertialParams::from_str(&in_file, "x.toml", 1, &ParamsOptions::default())
            .unwrap()
            .warnings
            .len(),
        1
    );
}

#[test]
fn physical_consistency_boundaries() {
    // A thin rod along x (moments 0, I, I) and a point mass (all zero) are physical limits.
    assert_eq!(check_physical(1.0, &[0.0, 0.0, 0.0, 0.1, 0.0, 0.1]), Ok(()));
    assert_eq!(check_physical(1.0, &[0.0; 6]), Ok(()));
    // A flat disc is exactly on the triangle boundary: Izz = Ixx + Iyy.
    assert_eq!(
        check_physical(1.0, &[0.25, 0.0, 0.0, 0.25, 0.0, 0.5]),
        Ok(())
    );
    assert!(matches!(
        check_physical(1.0, &[0.25, 0.0, 0.0, 0.25, 0.0, 0.51]),
        Err(NonPhysical::TriangleInequality { .. })
    ));
    // Products of inertia too large for the diagonal make the tensor indefinite.
    assert!(matches!(
        check_physical(1.0, &[0.1, 0.2, 0.0, 0.1, 0.0, 0.2]),
        Err(NonPhysical::NotPositiveSemidefinite { .. })
    ));
    assert!(matches!(
        check_physical(-0.1, &[0.0; 6]),
        Err(NonPhysical::NegativeMass { .. })
    ));
}

fn maybe(
    present: bool,
    s: impl Strategy<Value = Vec<f64>> + 'static,
) -> BoxedStrategy<Option<Vec<f64>>> {
    if present {
        s.prop_map(Some).boxed()
    } else {
        Just(None).boxed()
    }
}

fn traj_strategy() -> impl Strategy<Value = Trajectory> {
    (1usize..4, 1usize..20, any::<[bool; 3]>()).prop_flat_map(|(dof, n, [dq, ddq, tau])| {
        let block =
            move || prop::collection::vec(prop::num::f64::NORMAL | prop::num::f64::ZERO, n * dof);
        (
            Just((dof, n)),
            prop::collection::vec(1e-6..10.0f64, n),
            block(),
            maybe(dq, block()),
            maybe(ddq, block()),
            maybe(tau, block()),
        )
            .prop_map(|((dof, _), steps, q, dq, ddq, tau)| {
                let t = steps.iter().scan(-1.0, |acc, s| {
                    *acc += s;
                    Some(*acc)
                });
                Trajectory {
                    source: "roundtrip.csv".into(),
                    dof,
                    t: t.collect(),
                    q,
                    dq,
                    ddq,
                    tau,
                }
            })
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    /// Writing then reading gives back exactly the same numbers (shortest round-trip format).
    #[test]
    fn csv_round_trips_exactly(traj in traj_strategy()) {
        let mut buf = Vec::new();
        traj.write_csv(&mut buf).unwrap();
        let back = Trajectory::from_reader(buf.as_slice(), "roundtrip.csv", Some(traj.dof)).unwrap();
        prop_assert_eq!(back, traj);
    }

    #[test]
    fn loaders_never_panic_on_arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
        never_panics(&bytes);
    }

    #[test]
    fn loaders_never_panic_on_mutated_valid_files(seed in any::<u64>(), edits in 1usize..6) {
        for base in valid_samples() {
            never_panics(&mutate(&base, seed, edits));
        }
    }
}

fn valid_samples() -> Vec<Vec<u8>> {
    let arm = std::fs::read(
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("arms/puma560.toml"),
    )
    .expect("puma560.toml");
    let params = b"[[link]]\nm = 1.0\ncom = [0.1, 0.0, 0.0]\ninertia_com = [0.01, 0.0, 0.0, 0.01, 0.0, 0.01]\n[effects]\nviscous = [0.1]\n".to_vec();
    let csv = b"t,q1,dq1,ddq1,tau1\n0,1e-3,2,3,4\n0.5,1,2,3,4\n".to_vec();
    let urdf = br#"<robot name="r"><link name="base"/>
<link name="l1"><inertial><origin xyz="0.1 0 0" rpy="0 0 0"/><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
<link name="l2"><inertial><mass value="0.5"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.3" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
<joint name="j2" type="prismatic"><parent link="l1"/><child link="l2"/><origin xyz="0.4 0 0" rpy="1.57 0 0"/><axis xyz="0 -1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>"#
        .to_vec();
    vec![arm, params, csv, urdf]
}

/// Deterministic byte-level mutations: overwrite, insert, delete.
fn mutate(base: &[u8], seed: u64, edits: usize) -> Vec<u8> {
    use rand::Rng;
    let mut r = rng(seed);
    let mut v = base.to_vec();
    let alphabet = b"0123456789.,-+eE\n\r\"'[]=#nafiINFtq \x00\xff\x1f\x8b";
    for _ in 0..edits {
        let pos = r.gen_range(0..=v.len());
        let byte = alphabet[r.gen_range(0..alphabet.len())];
        match r.gen_range(0..3) {
            0 if pos < v.len() => v[pos] = byte,
            1 => v.insert(pos, byte),
            _ if pos < v.len() => {
                v.remove(pos);
            }
            _ => v.push(byte),
        }
    }
    v
}

pub fn never_panics(bytes: &[u8]) {
    if let Ok(text) = std::str::from_utf8(bytes) {
        let _ = DhTable::from_str(text, "fuzz.toml");
        let _ = dynid::urdf::import_str(text, "fuzz.urdf", &Default::default());
        for dof in [1, 2, 6] {
            let _ = InertialParams::from_str(text, "fuzz.toml", dof, &ParamsOptions::default());
            let _ = InertialParams::from_str(
                text,
                "fuzz.toml",
                dof,
                &ParamsOptions {
                    allow_nonphysical: true,
                },
            );
        }
    }
    for dof in [None, Some(1), Some(2)] {
        let _ = Trajectory::from_reader(bytes, "fuzz.csv", dof);
    }
}

/// Long fuzz-style run (run with `cargo test -- --ignored fuzz`; `DYNID_FUZZ_SECS`, default 600).
#[test]
#[ignore]
fn fuzz_loaders_for_minutes() {
    let secs: u64 = std::env::var("DYNID_FUZZ_SECS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(600);
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(secs);
    let bases = valid_samples();
    let mut cases = 0u64;
    let mut seed = 0u64;
    while std::time::Instant::now() < deadline {
        for base in &bases {
            never_panics(&mutate(base, seed, 1 + (seed % 8) as usize));
            cases += 1;
        }
        let mut random = rng(seed ^ 0xdead_beef);
        let len = rand::Rng::gen_range(&mut random, 0..300);
        let bytes: Vec<u8> = (0..len).map(|_| rand::Rng::gen(&mut random)).collect();
        never_panics(&bytes);
        cases += 1;
        seed += 1;
    }
    eprintln!("fuzz: {cases} inputs in {secs} s, no panic");
}

/// The fuzz seeds must themselves be valid, or mutating them only exercises the first error.
#[test]
fn fuzz_seeds_are_valid_inputs() {
    let seeds = valid_samples();
    let text = |i: usize| std::str::from_utf8(&seeds[i]).unwrap();
    DhTable::from_str(text(0), "seed.toml").expect("D-H seed");
    InertialParams::from_str(text(1), "seed.toml", 1, &ParamsOptions::default())
        .expect("params seed");
    Trajectory::from_reader(&seeds[2][..], "seed.csv", Some(1)).expect("CSV seed");
    let imported =
        dynid::urdf::import_str(text(3), "seed.urdf", &Default::default()).expect("URDF seed");
    assert_eq!(imported.table.joints.len(), 2);
}

/// `to_toml` writes what `from_str` reads back: the full vector to rounding of `MX = m·(MX/m)`
/// (a few ulp) and every effect array exactly.
#[test]
fn params_files_round_trip_through_the_writer() {
    use dynid::params::Effects;
    let mut r = rng(12);
    let p = cloud_params(&random_clouds(&mut r, 3));
    let effects = Effects {
        viscous: Some(vec![0.1, 0.2, 0.3]),
        coulomb: Some(vec![0.5, 0.0, 1.0 / 3.0]),
        stribeck: Some(vec![0.05, 0.0, 0.0]),
        loadcoulomb: Some(vec![0.0, 0.1, 0.2]),
        sign_velocity: Some(vec![0.01, 0.02, 0.0]),
        stribeck_velocity: Some(vec![0.1, 0.2, 0.3]),
        ..Effects::default()
    };
    let params = InertialParams::from_full_vector(&p, effects.clone());
    let text = params.to_toml(&["written by a test".into()]);
    let back = InertialParams::from_str(&text, "w.toml", 3, &ParamsOptions::default())
        .unwrap_or_else(|e| panic!("{e}\n{text}"));
    assert_close(&back.full_vector(), &p, 1e-15, "written and read back");
    assert_eq!(back.effects, effects);
    assert!(text.starts_with("# written by a test\n"));
}

/// The plant's friction with a smoothing velocity and a Stribeck term, against its closed form.
#[test]
fn params_effects_smoothed_friction_matches_its_closed_form() {
    use dynid::params::Effects;
    let e = Effects {
        coulomb: Some(vec![0.5]),
        stribeck: Some(vec![0.2]),
        viscous: Some(vec![0.1]),
        sign_velocity: Some(vec![0.01]),
        stribeck_velocity: Some(vec![0.3]),
        ..Effects::default()
    };
    for dq in [-1.0, -0.004, 0.0, 0.002, 0.5] {
        let s = (dq / 0.01f64).tanh();
        let want = 0.1 * dq + 0.5 * s + 0.2 * s * (-(dq / 0.3f64).powi(2)).exp();
        assert!((e.torque(0, 0.3, dq, 2.0) - want).abs() < 1e-15, "dq {dq}");
    }
    // Without a velocity the sign is exact and sign(0) = 0.
    let exact = Effects {
        coulomb: Some(vec![0.5]),
        ..Effects::default()
    };
    assert_eq!(exact.torque(0, 0.0, 1e-9, 0.0), 0.5);
    assert_eq!(exact.torque(0, 0.0, 0.0, 0.0), 0.0);
}

/// One list of `[effects]` keys: what the reader accepts is what the writer writes.
#[test]
fn every_effects_key_is_read_and_written() {
    let keys: Vec<&str> = dynid::params::Effects::default()
        .arrays()
        .iter()
        .map(|(k, _)| *k)
        .collect();
    assert_eq!(keys, dynid::params::KNOWN_EFFECTS);
}
