//! "Adding an arm = adding a TOML + `cargo build`": copy the crate to a scratch directory, add
//! `arms/<new>.toml`, build, and check that build.rs generated the kernels, that the new arm is
//! in the registry of the built binary, and that a second build regenerates nothing.
//!
//! Slow (a cargo build of the copied crate plus one generator run), so `#[ignore]`d:
//! `cargo test -- --ignored adding_an_arm`.

use std::path::Path;
use std::process::Command;

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let name = entry.file_name();
        if name == "__pycache__" || name == ".pytest_cache" || name == "target" {
            continue;
        }
        let (src, dst) = (entry.path(), to.join(&name));
        if entry.file_type().unwrap().is_dir() {
            copy_dir(&src, &dst);
        } else {
            std::fs::copy(&src, &dst).unwrap();
        }
    }
}

const NEW_ARM: &str = r#"name = "newarm"
convention = "modified"
gravity = [0.0, 0.0, -9.81]

[[joint]]
kind = "revolute"
alpha = 0.0
a = 0.0
d = 0.3
theta = 0.0

[[joint]]
kind = "prismatic"
alpha = -1.5707963267948966
a = 0.1
d = 0.0
theta = 0.0
"#;

#[test]
#[ignore]
fn adding_an_arm_is_adding_a_toml_and_building() {
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."));
    let scratch = tempfile::tempdir().unwrap();
    let copy = scratch.path().join("dynid");
    for dir in ["src", "macros", "codegen", "arms", "generated", "benches"] {
        copy_dir(&root.join(dir), &copy.join(dir));
    }
    for file in ["Cargo.toml", "Cargo.lock", "build.rs"] {
        std::fs::copy(root.join(file), copy.join(file)).unwrap();
    }
    std::fs::write(copy.join("arms/newarm.toml"), NEW_ARM).unwrap();

    // Share the main target dir so dependencies are not rebuilt (the copy's own crates get
    // distinct fingerprints because their path differs).
    let target =
        std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| root.join("target"), Into::into);
    let cargo = || {
        let mut c = Command::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()));
        c.current_dir(&copy)
            .env("CARGO_TARGET_DIR", &target)
            .env_remove("DYNID_MACROS_BASE");
        c
    };
    let build = || {
        let out = cargo()
            .args(["build", "--offline", "--profile", "test", "--bin", "dynid"])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "cargo build failed:\n{stderr}");
        stderr
    };

    let generated = copy.join("generated/newarm.rs");
    assert!(!generated.exists());
    let stamps = |dir: &Path| {
        let mut v: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| {
                let e = e.unwrap();
                (e.file_name(), e.metadata().unwrap().modified().unwrap())
            })
            .collect();
        v.sort();
        v
    };
    let before = stamps(&copy.join("generated"));

    let first = build();
    assert!(
        generated.exists(),
        "build.rs did not generate generated/newarm.rs:\n{first}"
    );
    let after = stamps(&copy.join("generated"));
    // Exactly the new arm was written; the existing files were left alone.
    assert_eq!(after.len(), before.len() + 1);
    assert!(
        before.iter().all(|b| after.contains(b)),
        "an existing generated file was rewritten"
    );

    let second = build();
    assert_eq!(
        stamps(&copy.join("generated")),
        after,
        "second build touched generated/"
    );
    assert!(
        !second.contains("Compiling"),
        "second build recompiled something:\n{second}"
    );

    // Editing one table regenerates exactly that arm.
    let scara = copy.join("arms/scara.toml");
    let mut text = std::fs::read_to_string(&scara).unwrap();
    text.push_str("# edited\n");
    std::fs::write(&scara, text).unwrap();
    build();
    let edited = stamps(&copy.join("generated"));
    for ((name, old), (_, new)) in after.iter().zip(&edited) {
        assert_eq!(
            old != new,
            name == "scara.rs",
            "{name:?}: only scara.rs may change"
        );
    }

    let out = cargo()
        .args([
            "run",
            "--offline",
            "--profile",
            "test",
            "--bin",
            "dynid",
            "--",
            "arms",
            "--json",
            "newarm",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json[0]["name"], "newarm");
    assert_eq!(json[0]["dof"], 2);
}
