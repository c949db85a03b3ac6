//! `arm!` error messages (trybuild snapshots in `tests/ui/*.stderr`; fixtures in
//! `tests/ui/fixtures/`): stale, missing, malformed or incomplete generated files and bad
//! arguments each give a `compile_error!` naming the arm, the file and the fix. Kept in this
//! crate so trybuild's scratch crate depends on the macro only (a few seconds, not minutes).

#[test]
fn macro_errors_name_the_arm_the_file_and_the_fix() {
    // Under trybuild the manifest dir is a scratch crate; relative `root`s resolve against this.
    std::env::set_var("DYNID_MACROS_BASE", env!("CARGO_MANIFEST_DIR"));
    let t = trybuild::TestCases::new();
    t.compile_fail("tests/ui/*.rs");
}
