"""One-line errors with exit code 2 for bad input, shared by every subcommand."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import NoReturn


class UsageError(Exception):
    """Invalid user input (flag, value, config, run directory). Reported in one line, exit code 2."""


class OneLineArgumentParser(argparse.ArgumentParser):
    """argparse, but a bad flag gives one line (``jaxsimrl <cmd>: error: ...``) and exit code 2."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        raise SystemExit(2)


def positive_int(text: str) -> int:
    """argparse type: a positive integer; accepts scientific notation such as ``2e5``."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if not value.is_integer() or value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return int(value)


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def seed_type(bits: int | None = None) -> Callable[[str], int]:
    """argparse type: a non-negative integer seed, below 2**bits when ``bits`` is given (the range the
    seeded generator accepts)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}") from None
        if value < 0 or (bits is not None and value >= 2**bits):
            bound = f"an integer in [0, 2**{bits})" if bits is not None else "a non-negative integer"
            raise argparse.ArgumentTypeError(f"expected {bound}, got {text!r}")
        return value

    return parse


def seed_list(bits: int | None = None) -> Callable[[str], tuple[int, ...]]:
    """argparse type: distinct seeds as a range ``0-15`` (both ends included) or a list ``0,3,7``, each
    as :func:`seed_type` accepts."""
    one = seed_type(bits)

    def parse(text: str) -> tuple[int, ...]:
        if "-" in text.strip("-"):
            first, _, last = text.partition("-")
            low, high = one(first), one(last)
            if high < low:
                raise argparse.ArgumentTypeError(f"empty seed range {text!r} (write LOW-HIGH)")
            return tuple(range(low, high + 1))
        seeds = tuple(one(part) for part in text.split(","))
        if len(set(seeds)) != len(seeds):
            raise argparse.ArgumentTypeError(f"seeds repeat in {text!r}: each agent needs its own")
        return seeds

    return parse


def fail(message: str) -> NoReturn:
    raise UsageError(message)
