"""``python -m codegen [ARM ...] [--check]``: regenerate ``generated/<arm>.rs`` from ``arms/<arm>.toml``
and ``generated/kernels.toml`` (the list of kernel kinds) from ``codegen/kernels.py``."""

from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from .dh import DhError
from .generate import Result, generate, write_atomic
from .kernels import MANIFEST, manifest


def _one(path: str) -> Result:
    return generate(Path(path))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m codegen", description=__doc__)
    ap.add_argument("arms", nargs="*", help="arm names (default: every arms/*.toml)")
    ap.add_argument("--arms-dir", default="arms", type=Path)
    ap.add_argument("--out-dir", default="generated", type=Path)
    ap.add_argument("--check", action="store_true", help="fail if a generated file is out of date; write nothing")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--manifest-only", action="store_true", help=f"only write (or --check) generated/{MANIFEST}")
    args = ap.parse_args(argv)

    stale = []
    target = args.out_dir / MANIFEST
    if args.check:
        if not target.exists() or target.read_text(encoding="utf-8") != manifest():
            stale.append(str(target))
    else:
        write_atomic(target, manifest())
    if args.manifest_only:
        if stale:
            print(f"error: out of date: {stale[0]} (run `python -m codegen --manifest-only`)", file=sys.stderr)
        return 1 if stale else 0

    if args.arms:
        paths = [args.arms_dir / f"{a}.toml" for a in args.arms]
    else:
        paths = sorted(args.arms_dir.glob("*.toml"))
    missing = [str(p) for p in paths if not p.is_file()]
    if missing:
        print(f"error: no such arm file: {', '.join(missing)}", file=sys.stderr)
        return 2
    try:
        with ProcessPoolExecutor(max_workers=max(1, min(args.jobs, len(paths)))) as pool:
            results = list(pool.map(_one, [str(p) for p in paths]))
    except (DhError, ValueError, ArithmeticError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"{'arm':<10} {'NB':>3} {'seconds':>8}  " + "  ".join(f"{k[0]:>18}" for k in results[0].ops))
    for r in results:
        target = args.out_dir / f"{r.arm}.rs"
        if args.check:
            if not target.exists() or target.read_text(encoding="utf-8") != r.text:
                stale.append(str(target))
            state = ""
        else:
            state = "written" if write_atomic(target, r.text) else "unchanged"
        cells = "  ".join(f"{f'{m}*/{a}+':>18}" for _, m, a in r.ops)
        print(f"{r.arm:<10} {r.nb:>3} {r.seconds:>8.2f}  {cells}  {state}")
    if stale:
        print(f"error: out of date: {', '.join(stale)} (run `python -m codegen`)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
