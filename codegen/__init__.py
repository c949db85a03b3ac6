"""dynid-codegen: D-H table -> dynamics equations -> straight-line Rust kernels.

Run ``python -m codegen [ARM ...]`` from the repository root; see ``codegen/FORMAT.md`` for the output.
"""

GENERATOR_VERSION = "0.3.8"
