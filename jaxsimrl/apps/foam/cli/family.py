"""``jaxsimrl family BASE [BASE ...] --out DIR``: a family of variant cases from base OpenFOAM cases
(foam_bridge._family), to train or evaluate a controller on many cases.

    jaxsimrl family my_case --out my_family --variants 8 --seed 0 --speed 0.5 1.5 --mesh 0.5 1

Writes DIR/<base name>-<k>/ (plain OpenFOAM cases, meshed) and DIR/family.json, one progress line per
case. Each base gets the same N variations (drawn from the ranges with the seed): variant k of every
base differs from its base alike. Bad input (a bad range, no such case, a variation that cannot apply
to a base, OpenFOAM missing) is one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import Any

from foam_bridge import CaseError, OpenFOAMNotFoundError, Variation, build_family, sample_variations
from jaxsimrl.cli.errors import fail, positive_int, seed_type

#: The range flags: (variation, what it does), in foam_bridge._family.VARIATION_NAMES's order.
RANGES = (("speed", "factor on the inlet velocity (and inlet turbulence)"),
          ("angle", "degrees added to the flow angle in the x-y plane (external flows)"),
          ("viscosity", "factor on nu (constant/transportProperties)"),
          ("mesh", "factor on the cells per block direction (blockMesh); 1, 2, 4 for a shipped mesh"),
          ("initial", "factor on 0/U's uniform internalField (0: start from rest)"))


def register(subparsers: Any) -> None:
    """Add the ``family`` subcommand."""
    parser = subparsers.add_parser(
        "family", help="write N variants of OpenFOAM cases (speed, angle, viscosity, mesh, initial field)",
        description="Copy each BASE to --out N times, each copy varied by values drawn uniformly from the "
        "given ranges (a variation without a range keeps the base's), meshed and ready to run; "
        "--out/family.json lists them. The bases are only read.")
    parser.add_argument("bases", metavar="BASE", type=Path, nargs="+", help="a simpleFoam case directory")
    parser.add_argument("--out", type=Path, metavar="DIR", required=True,
                        help="the family directory (created; variants of the same name are replaced)")
    parser.add_argument("--variants", type=positive_int, default=4, metavar="N",
                        help="variants per base (default 4)")
    parser.add_argument("--seed", type=seed_type(), default=0, metavar="S", help="sampling seed (default 0)")
    for name, meaning in RANGES:
        parser.add_argument(f"--{name}", type=float, nargs=2, metavar=("LO", "HI"), help=meaning)
    parser.set_defaults(func=run_family)


def ranges_of(args: argparse.Namespace) -> dict[str, tuple[float, float]]:
    """The ranges given on the command line, checked: LO <= HI, both valid for the variation."""
    ranges = {name: tuple(getattr(args, name)) for name, _ in RANGES if getattr(args, name) is not None}
    for name, (low, high) in ranges.items():
        if not low <= high:
            fail(f"--{name} {low:g} {high:g}: LO must not exceed HI")
        try:
            Variation(**{name: low}), Variation(**{name: high})
        except ValueError as err:
            fail(f"--{name}: {err}")
    return ranges  # type: ignore[return-value]


def run_family(args: argparse.Namespace) -> int:
    """Build the family of every base, one line per case built."""
    variations = sample_variations(ranges_of(args), args.variants, args.seed)
    total = args.variants * len(args.bases)
    built = 0

    def progress(case: Any) -> None:
        nonlocal built
        built += 1
        changed = ", ".join(f"{key} {value:g}" for key, value in dataclasses.asdict(case.variation).items()
                            if value != (0.0 if key == "angle" else 1.0)) or "as the base"
        print(f"[{built}/{total}] built {case.name}: {changed} (Re x {case.reynolds_ratio:.3g}, "
              f"{case.cells} cells)", flush=True)

    for base in args.bases:
        try:
            build_family(base, args.out, variations, progress=progress)
        except (ValueError, CaseError, OpenFOAMNotFoundError) as err:
            fail(" ".join(str(err).split()))
    print(f"wrote {args.out / 'family.json'} ({total} cases)")
    return 0
