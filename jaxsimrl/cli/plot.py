"""``jaxsimrl plot RUN_DIR``: the training curves of a run as one PNG, without a notebook.

Reads RUN_DIR/metrics.jsonl (and, for a host-env run, the iterations column of RUN_DIR/episodes.csv, its
failures by its application's failed outcomes, jaxsimrl.apps)
and writes RUN_DIR/training_curves.png, or ``--out FILE.png``. Needs no JAX.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from jaxsimrl.cli.errors import UsageError
from jaxsimrl.evaluation.curves import plot_training_curves, read_episode_iterations, read_rows
from jaxsimrl.plugin import application
from jaxsimrl.runs.run_dir import RunDir, read_json

PLOT_FILE = "training_curves.png"
EPISODES_FILE = "episodes.csv"


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``plot`` to the ``jaxsimrl`` dispatcher."""
    plot = subparsers.add_parser(
        "plot", help="plot a run's training curves (return, losses, entropy, KL) as PNG",
        description="Write the training curves of RUN_DIR (mean episode return with its 5-episode moving "
                    "average, policy and value loss, entropy, approx. KL and clip fraction, all against env "
                    f"steps; solver iterations per episode if RUN_DIR/{EPISODES_FILE} has them) to "
                    f"RUN_DIR/{PLOT_FILE}.")
    plot.add_argument("run_dir", metavar="RUN_DIR", help="a training run's directory")
    plot.add_argument("--out", metavar="FILE.png",
                      help=f"where to write the PNG (default: RUN_DIR/{PLOT_FILE})")
    plot.set_defaults(func=run_plot)


def run_plot(args: argparse.Namespace) -> int:
    """Entry point of ``jaxsimrl plot``."""
    run = Path(args.run_dir)
    out = Path(args.out) if args.out else run / PLOT_FILE
    if out.suffix.lower() != ".png":
        raise UsageError(f"--out {out} must end in .png")
    try:
        rows = read_rows(run)
    except ValueError as err:
        raise UsageError(str(err)) from None
    if not out.parent.is_dir():
        raise UsageError(f"--out {out}: directory {out.parent} does not exist")
    title = f"{run}: {rows[-1]['update']} updates, {int(rows[-1]['env_steps']):,} env steps"
    episodes = read_episode_iterations(run / EPISODES_FILE, _failed_outcomes(run))
    plot_training_curves(rows, out, title, episode_iterations=episodes)
    sys.stdout.write(f"wrote {out}\n")
    return 0


def _failed_outcomes(run: Path) -> frozenset[str]:
    """The failed episode outcomes of the application whose env the run's config.json names (none if
    no application's, or no readable config)."""
    try:
        record = read_json(RunDir(run).config)
    except ValueError:
        return frozenset()
    app = application(record.get("env") if isinstance(record, dict) else None)
    return app.failed_outcomes if app is not None else frozenset()
