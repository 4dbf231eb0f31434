"""A directory of eval-foam's reference runs, so that an evaluation does not run them again.

A reference is a long constant-factor run (100-190 s each on the full mesh) whose final U field every
run of its (geometry, velocity) is measured against. It is a pure function of what the solver is
given, so an entry is keyed by a SHA-256 of all of it: every FoamEnvConfig field that reaches the case
(not the work directory, the watchdog or ``keep_cases``), the inlet velocity, the factors, every file of
the case it starts from (the user's case or the built-in template), foam_bridge's source (which writes
the case) and the OpenFOAM installation. Anything else changed is a miss, never a stale hit.

An entry is ``KEY.npz`` (the final U field) and ``KEY.json`` (outcome, iterations, final residuals),
both written atomically, the JSON last: an entry without its JSON is incomplete and ignored. Only runs
that reached their iteration count with a field are stored (a crash may be the machine's, not the case's).
"""

from __future__ import annotations

import hashlib
import io
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import foam_bridge
from foam_bridge import find_openfoam
from jaxsimrl.apps.foam.config import foam_config_to_json
from jaxsimrl.runs.atomic import atomic_write_bytes, atomic_write_json

#: FoamEnvConfig fields that do not change what the solver computes.
_NOT_IN_KEY = ("work_dir", "keep_cases", "step_timeout_s")


@dataclass(frozen=True)
class CachedReference:
    """A stored reference run."""

    outcome: str
    iterations: int
    final_residuals: dict[str, float]
    final_u: np.ndarray


def reference_keys(cfg: Any, velocities: Sequence[float], factors: tuple[float, float]) -> dict[float, str]:
    """The hex digest naming the reference of ``cfg`` (a FoamEnvConfig) and ``factors`` at each of
    ``velocities``. The case files and foam_bridge's source are read once for all of them."""
    config = {k: v for k, v in foam_config_to_json(cfg).items() if k not in _NOT_IN_KEY}
    openfoam = find_openfoam(cfg.openfoam_path)
    shared = hashlib.sha256(json.dumps({"config": config, "factors": [float(f) for f in factors],
                                        "openfoam": [openfoam.path, openfoam.project_dir]},
                                       sort_keys=True).encode())
    bridge = Path(foam_bridge.__file__).parent  # holds the built-in template too
    for root in ([bridge] if cfg.case_dir is None else [Path(cfg.case_dir), bridge]):
        _hash_tree(shared, root)
    base = shared.hexdigest()
    return {v: hashlib.sha256(f"{base} {float(v)!r}".encode()).hexdigest() for v in velocities}


def _hash_tree(digest: Any, root: Path) -> None:
    """Add every regular file under ``root`` (name and bytes, in sorted order) to ``digest``.
    Bytecode caches and earlier solver output (time directories other than 0, logs) are left out."""
    for path in sorted(p for p in root.rglob("*") if p.is_file()):
        relative = path.relative_to(root)
        if "__pycache__" in relative.parts or (relative.parts[0].replace(".", "").isdigit()
                                               and relative.parts[0] != "0"):
            continue
        digest.update(str(relative).encode() + b"\0" + path.read_bytes() + b"\0")


class ReferenceCache:
    """Reference runs stored under ``directory`` (created on first store)."""

    def __init__(self, directory: str | Path) -> None:
        self.directory = Path(directory)

    def load(self, key: str) -> CachedReference | None:
        """The entry ``key``, or None when there is none (or it is incomplete or unreadable)."""
        meta_path, field_path = self.directory / f"{key}.json", self.directory / f"{key}.npz"
        try:
            meta = json.loads(meta_path.read_text())
            with np.load(field_path) as data:
                field = data["U"]
        except (OSError, ValueError, KeyError):
            return None
        return CachedReference(meta["outcome"], int(meta["iterations"]), dict(meta["final_residuals"]), field)

    def store(self, key: str, entry: CachedReference, about: dict[str, Any]) -> None:
        """Store ``entry`` (``about``: what it is, for a person reading the JSON)."""
        self.directory.mkdir(parents=True, exist_ok=True)
        buffer = io.BytesIO()
        np.savez(buffer, U=entry.final_u)
        atomic_write_bytes(self.directory / f"{key}.npz", buffer.getvalue())
        meta = {"outcome": entry.outcome, "iterations": entry.iterations,
                "final_residuals": entry.final_residuals, **about}
        atomic_write_json(self.directory / f"{key}.json", meta)
