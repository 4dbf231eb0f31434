"""Entry point of the ``jaxsimrl`` console script.

Each subcommand module exposes ``register(subparsers)``, which adds its parsers and sets
``func=run_function`` on them: the core's (SUBCOMMAND_MODULES), then each application's (its App's
``commands``, jaxsimrl.apps). Heavy imports (JAX, a solver's tooling) happen inside the run functions
so ``jaxsimrl --help`` and flag errors are instant.
"""

from __future__ import annotations

import argparse
import atexit
import importlib
import os
import sys

from jaxsimrl.cli.errors import OneLineArgumentParser, UsageError
from jaxsimrl.plugin import applications
from jaxsimrl.runs.signals import exit_code, stop_word, terminate_as_interrupt

# The core's modules that contribute subcommands; each application adds its own (jaxsimrl.apps).
SUBCOMMAND_MODULES = ("jaxsimrl.cli.lorenz", "jaxsimrl.cli.eval_lorenz", "jaxsimrl.cli.plot")


def build_parser() -> OneLineArgumentParser:
    """The ``jaxsimrl`` parser with every subcommand."""
    parser = OneLineArgumentParser(
        prog="jaxsimrl",
        description="Train deep-RL agents (pure-JAX PPO) to control scientific simulations.",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OneLineArgumentParser)
    subparsers.required = True
    for name in (*SUBCOMMAND_MODULES, *(module for app in applications() for module in app.commands)):
        importlib.import_module(name).register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``jaxsimrl argv``; returns the exit code (2 for bad input, 130 for Ctrl-C, 143 for SIGTERM,
    which takes Ctrl-C's path: jaxsimrl.runs.signals)."""
    return _run(argv)[0]


def entry() -> None:
    """The console script: :func:`main`, then the exit. A command that sets ``args.skip_teardown`` (a
    single-case ``solve``: every file it wrote is closed, no cluster or child is left to shut down) ends
    without the interpreter's teardown of JAX and matplotlib, which takes ~0.5 s of a 7-s solve (measured
    on 2 cores: benchmarks/results/solve-wall-2026-12-04)."""
    code, args = _run(None)
    if getattr(args, "skip_teardown", False):
        # what a normal exit runs before the teardown: multiprocessing's finalizers (else its resource
        # tracker warns of a leaked semaphore), JAX's and logging's handlers; only the teardown is skipped
        atexit._run_exitfuncs()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


def _run(argv: list[str] | None) -> tuple[int, argparse.Namespace]:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        with terminate_as_interrupt():
            return int(args.func(args) or 0), args
    except UsageError as err:
        sys.stderr.write(f"jaxsimrl {args.command}: error: {err}\n")
        return 2, args
    except KeyboardInterrupt as stop:
        sys.stderr.write(f"jaxsimrl {args.command}: {stop_word(stop)}\n")
        return exit_code(stop), args


if __name__ == "__main__":
    entry()
