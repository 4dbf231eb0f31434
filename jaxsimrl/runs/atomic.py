"""Atomic file writes for run directories and result files: the ``atomicfile`` package's, plus JSON.

A reader sees either the old file or the complete new one, never a partial one (``atomicfile`` is the
one implementation, shared with the solver bridge, which imports nothing of jaxsimrl).
"""

from __future__ import annotations

import json
import os
from typing import Any

from atomicfile import atomic_write_bytes, atomic_write_text, file_mode

__all__ = ["atomic_write_bytes", "atomic_write_json", "atomic_write_text", "file_mode"]


def atomic_write_json(path: str | os.PathLike[str], obj: Any, indent: int | None = 2) -> None:
    """Serialise ``obj`` as JSON (serialisation errors happen before anything is written) and write it."""
    atomic_write_text(path, json.dumps(obj, indent=indent, allow_nan=True) + "\n")
