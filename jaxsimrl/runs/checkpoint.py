"""Orbax checkpoints of a whole training state (any pytree of arrays) plus a JSON record of the run.

One checkpoint per chunk, numbered by the number of PPO updates done; only the last ``keep`` stay.
Saves are synchronous and orbax writes each one to a temporary directory that it renames when complete,
so a crash or Ctrl-C mid-save leaves the previous checkpoint as the latest one (the half-written
temporary directory is cleaned up the next time the directory is opened for writing).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import jax
import orbax.checkpoint as ocp

STATE_ITEM = "state"
META_ITEM = "meta"


class Checkpoints:
    """The checkpoint series of a run directory's ``checkpoints/`` folder."""

    def __init__(self, directory: str | Path, keep: int = 2, writable: bool = True) -> None:
        self.directory = Path(directory).absolute()
        if not writable and not self.directory.is_dir():
            raise ValueError(f"no checkpoint in {self.directory.parent} (missing {self.directory.name}/)")
        options = ocp.CheckpointManagerOptions(
            max_to_keep=keep,
            create=writable,
            enable_async_checkpointing=False,
            cleanup_tmp_directories=writable,
        )
        # Named handlers let a fresh manager read one item (or its metadata) without the other.
        handlers = {STATE_ITEM: ocp.StandardCheckpointHandler(), META_ITEM: ocp.JsonCheckpointHandler()}
        self._manager = ocp.CheckpointManager(self.directory, options=options, item_handlers=handlers)

    def __enter__(self) -> Checkpoints:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._manager.close()

    def steps(self) -> list[int]:
        """Steps (updates done) of the checkpoints on disk, oldest first."""
        self._manager.reload()
        return sorted(self._manager.all_steps())

    def latest_step(self) -> int:
        """The newest checkpoint's step; ValueError if there is none."""
        steps = self.steps()
        if not steps:
            raise ValueError(f"no checkpoint in {self.directory.parent} (nothing to resume or evaluate)")
        return steps[-1]

    def save(self, step: int, state: Any, meta: dict[str, Any]) -> None:
        """Save ``state`` (a pytree of arrays) and ``meta`` (JSON-serialisable) as checkpoint ``step``."""
        items = {STATE_ITEM: ocp.args.StandardSave(state), META_ITEM: ocp.args.JsonSave(meta)}
        args = ocp.args.Composite(**items)
        self._manager.save(step, args=args, force=True)
        self._manager.wait_until_finished()

    def read_meta(self, step: int | None = None) -> dict[str, Any]:
        """The JSON record of checkpoint ``step`` (default: the latest), without loading the state."""
        step = self.latest_step() if step is None else step
        self._item_metadata(step, META_ITEM)
        restored = self._restore(step, {META_ITEM: ocp.args.JsonRestore()})
        return dict(restored[META_ITEM])

    def restore(self, abstract_state: Any, step: int | None = None) -> tuple[Any, dict[str, Any]]:
        """Checkpoint ``step`` (default: the latest) restored into the structure of ``abstract_state``
        (e.g. a freshly initialised state, or ``jax.eval_shape`` of one); returns ``(state, meta)``.
        With ``abstract_state=None`` the state comes back as saved on disk: nested dicts of arrays.
        A damaged or incompatible checkpoint is a one-line ValueError."""
        step = self.latest_step() if step is None else step
        metadata = self._item_metadata(step, STATE_ITEM, META_ITEM)
        if abstract_state is not None:
            self._check_compatible(step, metadata[STATE_ITEM].tree, abstract_state)
        restored = self._restore(
            step, {STATE_ITEM: ocp.args.StandardRestore(abstract_state), META_ITEM: ocp.args.JsonRestore()})
        return restored[STATE_ITEM], dict(restored[META_ITEM])

    def restore_as_saved(self, step: int | None = None, device: jax.Device | None = None
                         ) -> tuple[Any, dict[str, Any]]:
        """Checkpoint ``step`` (default: the latest) as saved: nested dicts of arrays, all on ``device``
        (default: the first local one), whatever the run's device mesh was. For readers that need only
        part of a state (acting needs the parameters and the normaliser), or a state of an older layout.
        Returns ``(tree, meta)``."""
        step = self.latest_step() if step is None else step
        metadata = self._item_metadata(step, STATE_ITEM, META_ITEM)
        placed = jax.sharding.SingleDeviceSharding(device or jax.devices()[0])
        abstract = jax.tree.map(lambda leaf: jax.ShapeDtypeStruct(leaf.shape, leaf.dtype, sharding=placed),
                                metadata[STATE_ITEM].tree)
        restored = self._restore(
            step, {STATE_ITEM: ocp.args.StandardRestore(abstract), META_ITEM: ocp.args.JsonRestore()})
        return restored[STATE_ITEM], dict(restored[META_ITEM])

    # Everything below is checked before orbax restores anything: a failed orbax restore leaves
    # orphaned coroutines that print tracebacks at exit, which would bury the one-line error.
    def _item_metadata(self, step: int, *items: str) -> Any:
        """orbax's metadata of checkpoint ``step``, which must have ``items``."""
        try:
            metadata = self._manager.item_metadata(step)
        except Exception as err:  # orbax raises anything from KeyError to a bare Exception
            raise self._damaged(step, err) from None
        missing = [item for item in items if item not in metadata]
        if missing:
            raise self._damaged(step, f"no {'/'.join(missing)} item")
        return metadata

    def _restore(self, step: int, items: dict[str, Any]) -> Any:
        try:
            return self._manager.restore(step, args=ocp.args.Composite(**items))
        except Exception as err:  # a truncated or edited file: a page of TensorStore details
            raise self._damaged(step, err) from None

    def _damaged(self, step: int, reason: object) -> ValueError:
        text = (str(reason).splitlines() or [type(reason).__name__])[0][:200]
        return ValueError(f"checkpoint {step} in {self.directory} is damaged ({text}); remove it to fall "
                          f"back on the one before")

    def _check_compatible(self, step: int, stored_tree: Any, abstract_state: Any) -> None:
        """Compare the leaf names and shapes of the stored state with those of ``abstract_state``."""
        stored = ocp.tree.to_flat_dict(stored_tree, sep=".")
        wanted = ocp.tree.to_flat_dict(jax.eval_shape(lambda: abstract_state), sep=".")
        where = f"checkpoint {step} in {self.directory}"
        if set(stored) != set(wanted):
            odd = sorted(set(stored) ^ set(wanted))[:3]
            raise ValueError(f"{where} has a different state layout than its config gives (e.g. {odd})")
        for name, leaf in wanted.items():
            # Typed PRNG keys are stored as their raw uint32 data, of another shape: skip them.
            is_key = jax.dtypes.issubdtype(leaf.dtype, jax.dtypes.prng_key)
            if not is_key and tuple(stored[name].shape) != tuple(leaf.shape):
                raise ValueError(f"{where}: {name} has shape {tuple(stored[name].shape)}, expected "
                                 f"{tuple(leaf.shape)}")
