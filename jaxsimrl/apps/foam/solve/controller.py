"""The controller ``solve`` acts with: a train-foam run's policy, or the one shipped in the package.

A controller is a directory (jaxsimrl/apps/foam/controllers/README: config.json, a checkpoint,
provenance.json);
:func:`load_controller` loads its policy through :func:`jaxsimrl.policy.load_policy` (acting only: no
rollouts, no plotting) and says where it came from. JAX is imported here, in the driver only, and on first
use (:class:`BackgroundLoad` overlaps it with the case checks): the solver runs in spawned workers.
"""

from __future__ import annotations

import contextlib
import json
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from jaxsimrl.apps.foam.config import foam_config_from_json
from jaxsimrl.runs.run_dir import RunDir

#: The controller used when no --policy is given (files only; see jaxsimrl/apps/foam/controllers/__init__.py).
DEFAULT_CONTROLLER = Path(__file__).resolve().parents[1] / "controllers" / "default"
PROVENANCE = "provenance.json"


@dataclass(frozen=True)
class Controller:
    """A loaded policy (a ``jaxsimrl.policy.TrainedPolicy`` or anything with its ``act``,
    ``env_params`` and ``action_dim``) and its provenance (a JSON-ready dict)."""

    policy: Any
    provenance: dict[str, Any]


def load_controller(path: str | Path | None = None) -> Controller:
    """The policy of a run directory (default: the shipped controller); one-line ValueError if it is not a
    train-foam run."""
    from jaxsimrl.policy import load_policy  # JAX: seconds, overlapped by BackgroundLoad

    where = Path(path) if path is not None else DEFAULT_CONTROLLER
    policy = load_policy(where)
    if not hasattr(policy.env_params, "case_dir"):
        raise ValueError(f"{where} is not a train-foam run (its policy controls "
                         f"{policy.record.get('env')!r}); "
                         f"solve needs a foam controller")
    shipped = where.resolve() == DEFAULT_CONTROLLER.resolve()
    provenance = {"path": str(where), "default": shipped, "checkpoint": policy.checkpoint,
                  "update": policy.update, "env_steps": policy.env_steps, "actions": int(policy.action_dim)}
    file = where / PROVENANCE
    if file.is_file():
        provenance["recorded"] = json.loads(file.read_text())
    return Controller(policy, provenance)


def as_controller(policy: Any) -> Any:
    """``policy`` as solve takes it: a path or None stay (loaded later), a Controller stays, a loaded policy
    (``jaxsimrl.load_policy(run)``, anything with ``act`` and ``env_params``) becomes a Controller."""
    if policy is None or isinstance(policy, str | Path | Controller):
        return policy
    if not (hasattr(policy, "act") and hasattr(policy, "env_params")):
        raise ValueError(f"policy: expected a run directory, a Controller or a loaded policy, "
                         f"got {policy!r}")
    provenance = {"path": str(getattr(policy, "run_dir", None)), "default": False,
                  "checkpoint": getattr(policy, "checkpoint", None),
                  "update": getattr(policy, "update", None)}
    return Controller(policy, provenance)


def policy_env_config(path: str | Path | None) -> Any:
    """The FoamEnvConfig a controller trained with, from its config.json alone (no JAX); one-line
    ValueError if it has none."""
    record = RunDir.existing(path if path is not None else DEFAULT_CONTROLLER).read_config()
    if record.get("env") != "foam" or not isinstance(record.get("foam"), dict):
        raise ValueError(f"{path} is not a train-foam run (its config.json has env {record.get('env')!r}); "
                         f"solve needs a foam controller")
    return foam_config_from_json(record["foam"])


def warm_up(policy: Any) -> None:
    """Compile the policy's action for one observation now (the jitted forward pass compiles on its
    first call, ~0.7 s), so that the first real action costs what every later one does."""
    import numpy as np

    policy.act(np.zeros(policy.obs_dim, np.float32), None, deterministic=True)


class BackgroundLoad:
    """:func:`load_controller` and its :func:`warm_up` in a thread (importing JAX, reading the
    parameters and compiling the first action take seconds, which the case checks' subprocesses and the
    worker's start overlap); :meth:`result` waits and re-raises its error. Then, while the solver runs,
    the thread imports what the report draws with (``then``), off the end of the run."""

    def __init__(self, path: str | Path | None, then: Callable[[], Any] | None = None) -> None:
        self._path = path
        self._then = then
        self._result: Controller | None = None
        self._error: BaseException | None = None
        self._ready = threading.Event()
        # not a daemon: a process that exits (bad input, Ctrl-C) while the thread is inside XLA's compiler
        # aborts (SIGABRT, "exception not rethrown"); the exit waits for the load to end instead
        self._thread = threading.Thread(target=self._load, name="solve-load-controller", daemon=False)
        self._thread.start()

    def _load(self) -> None:
        try:
            loaded = load_controller(self._path)
            warm_up(loaded.policy)
            self._result = loaded
        except BaseException as err:  # noqa: BLE001 - handed to the caller by result()
            self._error = err
            return
        self._ready.set()
        if self._then is not None:
            with contextlib.suppress(Exception):  # only a head start: the report does it again if need be
                self._then()

    def result(self) -> Controller:
        while not self._ready.wait(0.05):  # not join(): the thread goes on with ``then``
            if not self._thread.is_alive():
                break
        if self._error is not None:
            raise self._error
        assert self._result is not None
        return self._result
