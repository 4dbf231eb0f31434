"""``jaxsimrl solve CASE [CASE ...] --pool N``: a campaign of cases (jaxsimrl.apps.foam.solve.campaign).

    jaxsimrl solve cases/ --pool 4 --out campaign --compare
    jaxsimrl solve cases/ --pool 4 --out campaign --compare --resume      # after a stop: the rest only

Kept apart from jaxsimrl/apps/foam/cli/solve.py, which hands over here when the command line names a campaign
(:func:`is_campaign`): a single CASE without these flags is a single solve, as it always was.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from foam_bridge import BACKENDS, ClusterError, OpenFOAMNotFoundError, PoolLostError, find_openfoam
from jaxsimrl.apps.foam.solve.campaign import find_cases, is_case, plan_campaign, run_campaign
from jaxsimrl.apps.foam.solve.campaign_table import (
    CAMPAIGN_CSV,
    CAMPAIGN_PNG,
    CONVERGED,
    SETTLED,
    finished_line,
)
from jaxsimrl.cli.errors import fail, positive_int
from jaxsimrl.cli.progress import RunProgress

#: --out of a campaign when none is given.
DEFAULT_OUT = "campaign"


def add_campaign_arguments(parser: argparse.ArgumentParser) -> None:
    """--pool, --backend, --ray-address and --resume on ``solve``'s parser."""
    group = parser.add_argument_group(
        "campaigns", "several CASEs, or a directory holding cases, or any of these flags: each case is "
        "solved into OUT/NAME.solved on a pool of workers; OUT/campaign.csv and OUT/campaign.png sum "
        "them up (default --out: ./campaign)")
    group.add_argument("--pool", type=positive_int, metavar="N",
                       help="workers, each solving one case at a time (default 1); with --compare each "
                       "also runs the case's own settings and the spread run beside a controller's run, so N "
                       "workers busy up to 3N cores")
    group.add_argument("--backend", choices=BACKENDS, help="where the workers run: local processes "
                       "(default) or a Ray cluster (OUT and the cases on a file system every node sees)")
    group.add_argument("--ray-address", metavar="ADDR", help="a running Ray cluster (with --backend ray; "
                       "default: a local Ray instance)")
    group.add_argument("--resume", action="store_true", help="go on with the campaign in --out: cases "
                       "whose solve finished (solve.json complete) are kept, the others solved")


def is_campaign(args: argparse.Namespace) -> bool:
    """Whether the command line asks for a campaign rather than one solve: several CASEs, a campaign flag,
    or one directory that is no case but holds some. Anything else is today's single solve, its errors
    included (a missing or broken CASE)."""
    if len(args.case) > 1 or args.resume or any(flag is not None for flag in
                                                 (args.pool, args.backend, args.ray_address)):
        return True
    path = Path(args.case[0])
    return path.is_dir() and not is_case(path) and any(is_case(inner) for inner in path.iterdir())


def run_campaign_command(args: argparse.Namespace, options: dict[str, Any]) -> int:
    """Plan, check and run the campaign; print its table's path. Exit 0 when every case converged or
    settled, 1 otherwise (a case oscillating, not converged or failed, or the pool lost), 2 for bad
    input."""
    backend = args.backend or "local"
    if args.ray_address is not None and backend != "ray":
        fail("--ray-address needs --backend ray")
    out = args.out if args.out is not None else Path.cwd() / DEFAULT_OUT
    try:
        if backend == "local":  # a Ray cluster's nodes may have OpenFOAM where this machine has not
            find_openfoam()
        jobs = plan_campaign(find_cases(args.case), out, args.resume)
    except (ValueError, OpenFOAMNotFoundError) as err:
        fail(" ".join(str(err).split()))
    pool = args.pool or 1
    with RunProgress("solve", stderr=True, every_line=True) as progress:
        def on_row(row: dict[str, Any], done: int, total: int) -> None:
            progress.step(finished_line(row), done, total)

        try:
            rows = run_campaign(jobs, out, pool, options, backend, args.ray_address, on_row, progress.say)
        except ClusterError as err:
            fail(" ".join(str(err).split()))
        except PoolLostError as err:
            sys.stderr.write(f"jaxsimrl solve: {err}; the cases finished are kept: run the same command "
                             f"with --resume to solve the others\n")
            return 1
    converged = sum(row["status"] == CONVERGED for row in rows)
    settled = sum(row["status"] == SETTLED for row in rows)
    print(f"{converged} of {len(jobs)} cases converged" + (f", {settled} settled" if settled else "")
          + f"; wrote {Path(out) / CAMPAIGN_CSV}, {Path(out) / CAMPAIGN_PNG} and a NAME.solved directory "
          "per case")
    return 0 if converged + settled == len(jobs) else 1
