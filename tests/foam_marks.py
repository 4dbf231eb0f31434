"""Marks shared by the foam test modules: tests that run the real simpleFoam."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from typing import TypeVar

import pytest

HAVE_OPENFOAM = shutil.which("simpleFoam") is not None
#: ``pytestmark = OPENFOAM`` marks a whole module.
OPENFOAM = [pytest.mark.openfoam, pytest.mark.skipif(not HAVE_OPENFOAM, reason="simpleFoam not on PATH")]

F = TypeVar("F", bound=Callable[..., object])


def needs_openfoam(test: F) -> F:
    """Mark a test that runs the real simpleFoam (skipped where it is not installed)."""
    for mark in OPENFOAM:
        test = mark(test)
    return test
