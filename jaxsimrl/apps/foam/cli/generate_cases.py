"""``jaxsimrl generate-cases DEST -n N --seed S``: N cheap steady 2-D simpleFoam cases of the geometry kinds
users run (foam_bridge's generator: steps, ribs, bumps, contractions, diffusers, bends), each with a user's
own factors and criterion, kept only if those converge it.

    jaxsimrl generate-cases runs/generated -n 6 --seed 0 --resolution 0.5 --workers 2

Writes DEST/<kind>-<k>/ (plain OpenFOAM cases, meshed; ``train-foam --family DEST`` takes them) and
DEST/generated.json, one progress line per case and a summary. Running it again on DEST with the same
seed goes on from what is there. Bad input (an unknown kind, N < 1, a resolution <= 0, OpenFOAM missing,
a DEST generated with other settings) is one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path
from typing import Any

from foam_bridge import (
    GEOMETRY_KINDS,
    CaseError,
    GeneratedCase,
    OpenFOAMNotFoundError,
    find_openfoam,
    generate_cases,
    read_generated,
)
from jaxsimrl.cli.errors import fail, positive_float, positive_int, seed_type


def register(subparsers: Any) -> None:
    """Add the ``generate-cases`` subcommand."""
    parser = subparsers.add_parser(
        "generate-cases", help="write N cheap steady 2-D OpenFOAM cases (steps, ribs, bumps, contractions, "
        "diffusers, bends), each converged by its own settings",
        description="Draw N case specs from the seed (geometry, Reynolds number, turbulence model, "
        "SIMPLE or SIMPLEC with a user's factors and criterion), write each as DEST/<kind>-<k>/ meshed by "
        "blockMesh, and run each once with its own settings: a case they do not converge within its endTime "
        "is rejected and another drawn. DEST/generated.json lists both; a second run on DEST goes on "
        "from it.")
    parser.add_argument("dest", metavar="DEST", type=Path, help="the output directory (created)")
    parser.add_argument("-n", type=positive_int, required=True, metavar="N", help="cases to accept")
    parser.add_argument("--seed", type=seed_type(), default=0, metavar="S", help="sampling seed (default 0)")
    parser.add_argument("--kinds", nargs="+", default=list(GEOMETRY_KINDS), metavar="KIND",
                        help=f"geometry kinds, cycled (default all: {' '.join(GEOMETRY_KINDS)})")
    parser.add_argument("--resolution", type=positive_float, default=1.0, metavar="R",
                        help="factor on the cells per direction (default 1: about 8,000 cells a case)")
    parser.add_argument("--workers", type=positive_int, default=1, metavar="W",
                        help="cases made at once, each simpleFoam on one core (default 1)")
    parser.add_argument("--no-own", dest="run_own", action="store_false",
                        help="do not run each case with its own settings (no rejection; faster)")
    parser.add_argument("--keep-unconverged", action="store_true",
                        help="keep a case whose own run reaches its endTime without meeting its criterion "
                             "(solve's --settle and the env's settle option are for such cases); a crash or "
                             "a divergence is still rejected")
    parser.set_defaults(func=run_generate_cases)


def _line(case: GeneratedCase) -> str:
    spec = case.spec
    reynolds = f"{spec.reynolds:.1e}".replace("e+0", "e").replace("e+", "e")  # 4.2e4, not 4.2e+04
    head = f"{case.name}: {spec.algorithm}, {spec.model}, Re {reynolds}, {case.cells:,} cells"
    if case.iterations is None:
        return head
    unmet = "" if case.converged else " (criterion never met)"
    return f"{head}, own {case.iterations} its {case.cpu_s:.1f} s{unmet}"


def run_generate_cases(args: argparse.Namespace) -> int:
    """Generate the cases, one line per case made or rejected, then a summary."""
    unknown = [kind for kind in args.kinds if kind not in GEOMETRY_KINDS]
    if unknown:
        fail(f"--kinds: unknown kind(s) {', '.join(unknown)}; known: {', '.join(GEOMETRY_KINDS)}")
    accepted = 0

    def progress(result: Any) -> None:
        nonlocal accepted
        if isinstance(result, GeneratedCase):
            accepted += 1
            print(f"[{accepted}/{args.n}] {_line(result)}", flush=True)
        else:
            print(f"[-] {result.spec.name} rejected: {result.reason}", flush=True)

    try:
        find_openfoam()
        cases = generate_cases(args.dest, args.n, args.seed, kinds=args.kinds, resolution=args.resolution,
                               workers=args.workers, run_own=args.run_own,
                               keep_unconverged=args.keep_unconverged, progress=progress)
    except (ValueError, CaseError, OpenFOAMNotFoundError) as err:
        fail(" ".join(str(err).split()))
    rejected = read_generated(args.dest).get("rejected", [])
    reasons = Counter(entry["reason"].split(":")[0].split(" (")[0] for entry in rejected)
    why = ", ".join(f"{count} {reason}" for reason, count in reasons.most_common())
    cpu = sum(case.cpu_s or 0.0 for case in cases)
    short = "" if len(cases) >= args.n else f" (only {len(cases)} of {args.n}: too many rejected)"
    print(f"accepted {len(cases)}{short}, rejected {len(rejected)}{f' ({why})' if why else ''}; own runs "
          f"{cpu:.1f} CPU s; wrote {args.dest / 'generated.json'}")
    return 0
