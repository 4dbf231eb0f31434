"""The code that runs inside a worker (a pool process or a Ray actor): it hosts FoamCaseEnv instances.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

A worker owns a fixed set of env ids. The driver sends it a batch of ``Request`` s (reset / step /
close of one env each) and gets one ``Reply`` per request, in order. Envs are created lazily on their
first request, in ``work_dir/env_<id>`` on the worker's own file system, so a restarted worker (after
a crash) simply rebuilds its cases. Before an env is (re)created, solver processes left behind by a
dead predecessor in that case directory are killed (see ``reaper``).

Exceptions raised by an env are caught and returned as a failed ``Reply``: the driver decides what
they mean (a failed step ends the episode; a failed reset is retried, then reported).
"""

from __future__ import annotations

import os
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

from foam_bridge._backends.reaper import kill_processes_under
from foam_bridge._env import FoamCaseEnv

__all__ = ["BAD_INPUT_ERRORS", "METHODS", "EnvFactory", "EnvHost", "Reply", "Request", "env_dir"]

METHODS = ("reset", "step", "close")
#: Exceptions that mean the config or case is unusable (every env would fail alike): not retried.
BAD_INPUT_ERRORS = ("ValueError", "CaseError", "OpenFOAMNotFoundError")


class Request(NamedTuple):
    """One call on one env: ``method`` in METHODS; ``args`` are its keyword arguments."""

    env_id: int
    method: str
    args: dict[str, Any]
    #: The batch's sequence number (set by Backend.run); its replies carry it back.
    seq: int = 0


class Reply(NamedTuple):
    """The answer to one Request.

    ``ok`` False: ``error`` is "ExceptionType: message" (``kind`` the type's name, ``where`` the
    raising file:line), or, with ``worker_died`` set, why the worker died: "worker died", or "node
    lost: IP/NODE" for a Ray actor whose node died.
    """

    env_id: int
    ok: bool
    value: Any = None
    error: str = ""
    worker_died: bool = False
    kind: str = ""
    where: str = ""
    seq: int = 0


#: Builds a worker's env: ``make_env(cfg, work_dir, env_id)``; None means FoamCaseEnv. It travels to the
#: worker, so it must pickle (a module-level class or function); foam_bridge._standin's StandIn is one.
EnvFactory = Callable[[Any, Path, int], Any]


def env_dir(work_dir: Path, env_id: int) -> Path:
    """The case directory FoamCaseEnv(cfg, work_dir, env_id) uses (each env its own; nothing in the cwd)."""
    return Path(work_dir) / f"env_{env_id}"


class EnvHost:
    """The FoamCaseEnv instances of one worker, created on demand, driven by Requests."""

    def __init__(self, cfg: Any, work_dir: Path, make_env: EnvFactory | None = None) -> None:
        self.cfg = cfg
        self.work_dir = Path(work_dir)
        self.make_env = make_env
        self.envs: dict[int, Any] = {}

    def _env(self, env_id: int) -> Any:
        if env_id not in self.envs:
            kill_processes_under(env_dir(self.work_dir, env_id))
            if self.make_env is not None:
                self.envs[env_id] = self.make_env(self.cfg, self.work_dir, env_id)
            else:
                self.envs[env_id] = FoamCaseEnv(self.cfg, work_dir=self.work_dir, env_id=env_id)
        return self.envs[env_id]

    def handle(self, request: Request) -> Reply:
        """Run one request; an exception becomes a failed Reply naming it (the worker keeps serving)."""
        try:
            if request.method == "close":
                env = self.envs.pop(request.env_id, None)
                if env is not None:
                    env.close()
                return Reply(request.env_id, True, seq=request.seq)
            if request.method not in METHODS:
                raise ValueError(f"unknown method {request.method!r}")
            value = getattr(self._env(request.env_id), request.method)(**request.args)
            return Reply(request.env_id, True, value, seq=request.seq)
        except Exception as err:  # noqa: BLE001 - reported to the driver, which owns the policy
            last = traceback.extract_tb(err.__traceback__)[-1:]
            where = f"{last[0].filename}:{last[0].lineno}" if last else ""
            kind = type(err).__name__
            return Reply(request.env_id, False, error=f"{kind}: {err}", kind=kind, where=where,
                         seq=request.seq)

    def handle_batch(self, requests: list[Request]) -> list[Reply]:
        """Run requests in order (envs of one worker share its core, so sequential is right)."""
        return [self.handle(request) for request in requests]

    def close(self) -> None:
        """Close every env (kills their solvers)."""
        for env_id in list(self.envs):
            self.handle(Request(env_id, "close", {}))

    def pid(self) -> int:
        """The worker's process id (tests kill it to simulate a crashed worker)."""
        return os.getpid()
