"""A checkpoint's acting part as plain arrays, read without orbax (``RUN/acting.npz``).

Acting needs three entries of a training checkpoint: the network parameters, the observation statistics
and the update counter. Restoring them through orbax costs about a second plus importing orbax and
TensorStore, most of ``jaxsimrl solve``'s wait for its first action on a small case (benchmarks/
RESULTS_solve.md). :func:`export_acting_arrays` writes those entries of one checkpoint to
``RUN/acting.npz`` (numpy's format: no pickle), with the checkpoint's step and a fingerprint of its files;
:func:`read_acting_arrays` hands them back only while that checkpoint is still the one asked for (same
step, same bytes), else None, and the caller restores with orbax. So a stale file is never used: a run
that trained on, or a controller whose checkpoint was replaced, falls back on orbax by itself.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np

from jaxsimrl.runs.atomic import atomic_write_bytes
from jaxsimrl.runs.run_dir import RunDir

__all__ = ["ACTING_FILE", "export_acting_arrays", "read_acting_arrays"]

ACTING_FILE = "acting.npz"
#: The checkpoint entries acting reads (jaxsimrl.policy.loading); update_step is optional there.
ACTING_ENTRIES = ("params", "normalizer", "update_step")
_HEADER = "__header__"
_SEP = "/"


def export_acting_arrays(run_dir: str | Path, checkpoint: int | None = None) -> Path:
    """Write ``run_dir/acting.npz`` from checkpoint ``checkpoint`` (default: the latest); returns its path."""
    import io

    from jaxsimrl.runs.checkpoint import Checkpoints  # orbax: only to write the file

    run = RunDir.existing(run_dir)
    with Checkpoints(run.checkpoints, writable=False) as checkpoints:
        step = checkpoints.latest_step() if checkpoint is None else checkpoint
        tree, meta = checkpoints.restore_as_saved(step)
    kept = {name: tree[name] for name in ACTING_ENTRIES if name in tree}
    if not {"params", "normalizer"} <= set(kept):
        raise ValueError(f"checkpoint {step} in {run.checkpoints} holds no network parameters and "
                         f"observation statistics")
    header = {"step": step, "fingerprint": _fingerprint(run.checkpoints / str(step)),
              "meta": {key: meta[key] for key in ("update", "env_steps") if key in meta}}
    buffer = io.BytesIO()
    np.savez(buffer, **_flatten(kept), **{_HEADER: np.asarray(json.dumps(header))})
    atomic_write_bytes(run.path / ACTING_FILE, buffer.getvalue())
    return run.path / ACTING_FILE


Exported = tuple[int, dict[str, Any], dict[str, Any]]


def read_acting_arrays(run: RunDir, checkpoint: int | None) -> Exported | None:
    """(step, tree, meta) of checkpoint ``checkpoint`` (None: the latest) from ``run``'s acting.npz, as
    orbax's ``restore_as_saved`` would give its acting entries; None when there is no such file or it was
    written from another checkpoint than the one asked for."""
    file = run.path / ACTING_FILE
    if not file.is_file():
        return None
    with np.load(file, allow_pickle=False) as data:
        header = json.loads(str(data[_HEADER]))
        arrays = {name: data[name] for name in data.files if name != _HEADER}
    steps = run.checkpoint_steps()
    wanted = checkpoint if checkpoint is not None else (steps[-1] if steps else None)
    step = header.get("step")
    if step != wanted or step not in steps or header.get("fingerprint") != _fingerprint(
            run.checkpoints / str(step)):
        return None
    return step, _unflatten(arrays), dict(header.get("meta", {}))


def _fingerprint(directory: Path) -> str:
    """sha256 over the relative names and bytes of every file under ``directory`` (a checkpoint: ~200 kB)."""
    digest = hashlib.sha256()
    for path in sorted(p for p in directory.rglob("*") if p.is_file()):
        digest.update(str(path.relative_to(directory)).encode() + b"\0")
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _flatten(tree: Any, prefix: str = "") -> dict[str, np.ndarray]:
    if not isinstance(tree, dict):
        return {prefix: np.asarray(tree)}
    flat: dict[str, np.ndarray] = {}
    for key, value in tree.items():
        if _SEP in key:
            raise ValueError(f"checkpoint entry {key!r}: {_SEP!r} in a key cannot be stored flat")
        flat.update(_flatten(value, f"{prefix}{_SEP}{key}" if prefix else key))
    return flat


def _unflatten(flat: dict[str, np.ndarray]) -> dict[str, Any]:
    tree: dict[str, Any] = {}
    for name, value in flat.items():
        *parents, leaf = name.split(_SEP)
        node = tree
        for key in parents:
            node = node.setdefault(key, {})
        node[leaf] = value
    return tree
