#!/usr/bin/env bash
# The project's one test command. On a machine with only the Rust toolchain and Python ≥ 3.10:
# makes (first run) or reuses the project-local virtual environment .venv/ with every pinned test
# dependency (scripts/venv.sh), then runs every Rust test (`cargo test`: the library, the CLI,
# the macro's compile-fail tests, the Pinocchio comparison of the URDF import) and every Python
# test (pytest), the Python bindings' after building them into .venv/ (maturin). A missing tool is a
# failure that says how to fix it, never a skip.
#
#   scripts/test.sh                 # everything
#   scripts/test.sh -- NAME         # extra arguments go to `cargo test` (e.g. a test filter)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
command -v cargo >/dev/null || { echo "error: cargo not found — install the Rust toolchain (rustup.rs)" >&2; exit 2; }
# shellcheck source=scripts/venv.sh
source scripts/venv.sh
dynid_venv "$ROOT"
[[ "${1:-}" == "--" ]] && shift

echo "=== cargo test ===" >&2
cargo test "$@"
echo "=== pytest ===" >&2
python -m pytest -q codegen
# The Python bindings (python/, issue 20): built into .venv/ by maturin (profile `python`: release without LTO),
# then their tests; the CLI they compare against is the one `cargo test` just built.
echo "=== maturin develop (python/) + pytest python/tests ===" >&2
maturin develop --profile python --quiet -m python/Cargo.toml
DYNID_CLI="$ROOT/target/debug/dynid" python -m pytest -q python/tests
