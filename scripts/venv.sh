# Sourced by scripts/test.sh and .ci/run: makes (or reuses) the project-local virtual environment
# `.venv/` with every pinned Python package the generator, the tests, the linters and the benches
# use (requirements.txt at the repository root pulls in the per-area files), and puts it first on
# the PATH. Reused while the requirement files and the interpreter are unchanged; re-synced (not
# rebuilt) when they change. Needs only Python ≥ 3.10 with its `venv` module, and PyPI.
#
# Knobs: DYNID_VENV (where, default <repo>/.venv), DYNID_BOOTSTRAP_PYTHON (the interpreter that
# creates it, default: the newest python3.x ≥ 3.10 on the PATH).

dynid_venv() {
  local root="$1"
  local venv="${DYNID_VENV:-$root/.venv}"
  local py="${DYNID_BOOTSTRAP_PYTHON:-}"
  if [[ -z "$py" ]]; then
    local c
    for c in python3 python3.14 python3.13 python3.12 python3.11 python3.10; do
      if command -v "$c" >/dev/null 2>&1 &&
        "$c" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 10) else 1)' 2>/dev/null; then
        py="$c"
        break
      fi
    done
  fi
  if [[ -z "$py" ]]; then
    echo "error: no Python ≥ 3.10 found (tried python3, python3.14 … python3.10) — install one, or set DYNID_BOOTSTRAP_PYTHON to its path" >&2
    return 2
  fi
  # What the environment must hold: the requirement files' bytes and the interpreter's version.
  local want
  want="$(cat "$root"/requirements.txt "$root"/codegen/requirements.txt "$root"/tests/requirements.txt |
    sha256sum | cut -c1-16) $("$py" -c 'import sys; print("%d.%d.%d" % sys.version_info[:3])')"
  if [[ -x "$venv/bin/python" && -f "$venv/.dynid-ready" && "$(cat "$venv/.dynid-ready")" == "$want" ]]; then
    echo "[venv] reusing $venv" >&2
  else
    if [[ ! -x "$venv/bin/python" ]]; then
      echo "[venv] creating $venv with $py ($("$py" --version 2>&1))" >&2
      if ! "$py" -m venv "$venv"; then
        echo "error: \`$py -m venv $venv\` failed — install your Python's venv module (Debian/Ubuntu: apt install python3-venv)" >&2
        return 2
      fi
    fi
    echo "[venv] installing the pinned packages (requirements.txt) into $venv ..." >&2
    if ! "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$root/requirements.txt"; then
      echo "error: pip could not install requirements.txt into $venv — check the network to PyPI, then run the command again" >&2
      return 2
    fi
    echo "$want" >"$venv/.dynid-ready"
  fi
  export VIRTUAL_ENV="$venv"
  export PATH="$venv/bin:$PATH"
  # The generator (build.rs) and the tests that call Python use this interpreter.
  export DYNID_PYTHON="$venv/bin/python"
}
