"""What every training run shares: its config.json record and its restore from a checkpoint.

A run's config.json names what it is (a fresh run's identity, stamped ``created_utc``) or, resumed, keeps
the record it was written with and adds this resume to ``resumed_utc``; after the run's own fields come
the versions of JAX and jaxsimrl it ran with. A checkpoint that does not fit the run's trainer is a
:class:`ResumeError` (one line), as is every input a run cannot start with (:class:`RunInputError`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any


class RunInputError(ValueError):
    """The run cannot start as given (a config, a batch too large for memory): one line."""


class ResumeError(RunInputError):
    """The run's checkpoint cannot be restored into this run's trainer (one line, "cannot resume: ...")."""


def config_record(fresh: Mapping[str, Any], resumed: Mapping[str, Any] | None, fields: Mapping[str, Any],
                  last: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """config.json of a run: ``fresh`` stamped with ``created_utc`` (a new run) or the ``resumed`` run's
    record, then ``fields``, the JAX and jaxsimrl versions and ``last``; a resume is added to
    ``resumed_utc``."""
    from importlib.metadata import version

    import jax

    now = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    base = dict(resumed) if resumed is not None else {**fresh, "created_utc": now}
    record = {**base, **fields, "jax_version": jax.__version__, "jaxsimrl_version": version("jaxsimrl"),
              **(last or {})}
    if resumed is not None:
        record["resumed_utc"] = [*base.get("resumed_utc", []), now]
    return record


def restore(checkpoints: Any, trainer: Any, key: Any, step: int) -> tuple[Any, dict[str, Any]]:
    """(state, meta) of checkpoint ``step``, in the shapes of ``trainer.init(key)`` (not computed: orbax
    restores the saved shardings); ResumeError if it does not fit."""
    import jax

    try:
        return checkpoints.restore(jax.eval_shape(trainer.init, key), step)
    except ValueError as err:
        raise ResumeError(f"cannot resume: {err}") from None
