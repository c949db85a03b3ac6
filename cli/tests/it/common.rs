//! Shared test helpers: tables, random physical parameters built from point masses, states.

use dynid::dh::DhTable;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// Parses a table written in a test; panics with the loader's message on error.
pub fn table(text: &str) -> DhTable {
    DhTable::from_str(text, "test.toml").unwrap_or_else(|e| panic!("{e}"))
}

pub const PLANAR2: &str = r#"
name = "planar2"
convention = "modified"
gravity = [0.0, -9.81, 0.0]
[[joint]]
kind = "revolute"
alpha = 0.0
a = 0.0
d = 0.0
theta = 0.0
[[joint]]
kind = "revolute"
alpha = 0.0
a = 1.0
d = 0.0
theta = 0.0
"#;

/// A spatial chain with every feature: twists, offsets, a prismatic joint with a fixed angle,
/// gravity along an oblique direction.
pub const MIXED4: &str = r#"
name = "mixed4"
convention = "modified"
gravity = [1.0, -2.0, -9.5]
[[joint]]
kind = "revolute"
alpha = 0.3
a = 0.1
d = 0.2
theta = 0.4
[[joint]]
kind = "prismatic"
alpha = -1.5707963267948966
a = 0.05
d = 0.3
theta = 0.7
[[joint]]
kind = "revolute"
alpha = 1.2
a = 0.4
d = -0.1
theta = -0.5
[[joint]]
kind = "revolute"
alpha = -0.8
a = 0.0
d = 0.15
theta = 0.0
"#;

/// Every table under `arms/`, plus the built-in test tables.
pub fn all_tables() -> Vec<DhTable> {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/..", "/arms");
    let mut paths: Vec<_> = std::fs::read_dir(dir)
        .expect("arms/ exists")
        .map(|e| e.expect("readable dir entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    paths.sort();
    let mut tables: Vec<DhTable> = paths
        .iter()
        .map(|p| DhTable::from_path(p).unwrap_or_else(|e| panic!("{e}")))
        .collect();
    assert!(
        tables.len() >= 4,
        "expected at least planar2, puma560, panda, scara in arms/"
    );
    tables.push(table(PLANAR2));
    tables.push(table(MIXED4));
    tables
}

/// Point masses `(m, r)` of one link, `r` in the link frame.
pub type Cloud = Vec<(f64, [f64; 3])>;

/// Random rigid bodies as clouds of 4 point masses (so always physically consistent, with a
/// full inertia tensor), one per link.
pub fn random_clouds(rng: &mut impl Rng, dof: usize) -> Vec<Cloud> {
    (0..dof)
        .map(|_| {
            (0..4)
                .map(|_| {
                    let m = rng.gen_range(0.2..3.0);
                    let r = [
                        rng.gen_range(-0.4..0.4),
                        rng.gen_range(-0.4..0.4),
                        rng.gen_range(-0.4..0.4),
                    ];
                    (m, r)
                })
                .collect()
        })
        .collect()
}

/// Full parameters about each link origin, straight from the definitions
/// `I = Σ m(|r|²·1 − r rᵀ)`, `h = Σ m r`, `M = Σ m` (Khalil order).
pub fn cloud_params(clouds: &[Cloud]) -> Vec<f64> {
    let mut p = Vec::new();
    for cloud in clouds {
        let mut l = [0.0; 10];
        for &(m, [x, y, z]) in cloud {
            l[0] += m * (y * y + z * z);
            l[1] -= m * x * y;
            l[2] -= m * x * z;
            l[3] += m * (x * x + z * z);
            l[4] -= m * y * z;
            l[5] += m * (x * x + y * y);
            l[6] += m * x;
            l[7] += m * y;
            l[8] += m * z;
            l[9] += m;
        }
        p.extend_from_slice(&l);
    }
    p
}

/// A random state `(q, q̇, q̈)`; prismatic coordinates stay within ±0.5 m.
pub fn random_state(rng: &mut impl Rng, dof: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let v = |rng: &mut dyn rand::RngCore, s: f64| {
        (0..dof).map(|_| rng.gen_range(-s..s)).collect::<Vec<_>>()
    };
    (v(rng, 0.5 * std::f64::consts::PI), v(rng, 2.0), v(rng, 5.0))
}

/// `‖a − b‖∞ ≤ rel · max(1, ‖b‖∞)`, with a message naming what is compared.
pub fn assert_close(a: &[f64], b: &[f64], rel: f64, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths differ");
    let scale = b.iter().fold(1.0f64, |m, x| m.max(x.abs()));
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert!(
            (x - y).abs() <= rel * scale,
            "{what}[{i}]: {x} vs {y} (scale {scale}, rel {rel})"
        );
    }
}

/// `out = A·x` for a row-major `A` with `x.len()` columns.
pub fn mat_vec(a: &[f64], x: &[f64]) -> Vec<f64> {
    a.chunks(x.len())
        .map(|row| row.iter().zip(x).map(|(r, v)| r * v).sum())
        .collect()
}

/// The paper's closed-form base regressor Φ of planar2 (a1 = 1, g = 9.81), row-major 2×6.
pub fn planar2_phi(q: &[f64], dq: &[f64], ddq: &[f64]) -> [f64; 12] {
    let (a1, g) = (1.0, 9.81);
    let (s1, c1) = q[0].sin_cos();
    let (s2, c2) = q[1].sin_cos();
    let (s12, c12) = (q[0] + q[1]).sin_cos();
    let (dq1, dq2, ddq1, ddq2) = (dq[0], dq[1], ddq[0], ddq[1]);
    [
        ddq1,
        g * c1,
        -g * s1,
        ddq1 + ddq2,
        a1 * (2.0 * ddq1 + ddq2) * c2 - a1 * (2.0 * dq1 + dq2) * dq2 * s2 + g * c12,
        -a1 * (2.0 * ddq1 + ddq2) * s2 - a1 * (2.0 * dq1 + dq2) * dq2 * c2 - g * s12,
        0.0,
        0.0,
        0.0,
        ddq1 + ddq2,
        a1 * ddq1 * c2 + a1 * dq1 * dq1 * s2 + g * c12,
        -a1 * ddq1 * s2 + a1 * dq1 * dq1 * c2 - g * s12,
    ]
}

/// The paper's base parameters θ = [ZZ1 + a1²M2, MX1 + a1M2, MY1, ZZ2, MX2, MY2] (a1 = 1).
pub fn planar2_theta(p: &[f64]) -> [f64; 6] {
    [p[5] + p[19], p[6] + p[19], p[7], p[15], p[16], p[17]]
}

/// The Python the tests call: `DYNID_PYTHON` (set by scripts/test.sh), else the project's
/// `.venv/` when it exists, else `python3` on the `PATH` — the same rule as build.rs.
pub fn project_python() -> std::path::PathBuf {
    if let Some(p) = std::env::var_os("DYNID_PYTHON") {
        return p.into();
    }
    let venv =
        std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join(".venv/bin/python");
    if venv.exists() {
        return venv;
    }
    "python3".into()
}

/// Runs the `dynid` binary under test.
pub fn dynid(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_dynid"))
        .args(args)
        .output()
        .expect("run dynid")
}

/// Runs the project's Python on `script` (relative to the crate) with `--dynid <binary under
/// test>` and `args`; prints its output and fails the test unless it exits 0 (77: a library is
/// missing — the test command installs it). Returns the output text.
pub fn python_script(script: &str, args: &[&std::ffi::OsStr]) -> String {
    let path = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join(script);
    let o = std::process::Command::new(project_python())
        .arg(&path)
        .args(["--dynid", env!("CARGO_BIN_EXE_dynid")])
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("run {script}: {e}"));
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    eprintln!("{text}");
    assert!(
        o.status.success(),
        "{script} failed (exit {:?}; 77 = numpy, Pinocchio, MuJoCo or mcap missing: run scripts/test.sh):\n{text}",
        o.status.code()
    );
    text
}

/// A numeric CSV file (a trajectory, a log): its header line and its rows as numbers.
pub fn read_csv(path: &std::path::Path) -> (String, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_string();
    let rows = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    (header, rows)
}
