"""The Ray backend: workers are Ray actors (one CPU each), so envs can live on any node of a cluster.

Each actor hosts its envs exactly like a local worker (``worker.EnvHost``), with the case directories
under ``work_dir`` on the actor's own node. ``ray`` is imported only when this backend is used. If Ray
is not initialised yet, ``ray.init(address=ray_address)`` is called (``None`` starts a local instance).
An actor that dies (RayActorError) or misses the batch deadline is killed and replaced; its solvers
die with its process (PR_SET_PDEATHSIG, see foam_bridge.solver), on whatever node it ran.

Security: Ray's processes listen on every interface. Ray >= 2.59 (RAY_MIN_VERSION, required) turns on
token authentication for a local instance started by ``ray.init()``; an older Ray would let anyone who
can reach the ports run code as this user, so it is refused. For a multi-node cluster, start every node
with ``RAY_AUTH_MODE=token`` (see the README).
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Any

from foam_bridge.backends.base import Backend, close_deadline_s
from foam_bridge.backends.worker import EnvHost, Reply, Request

#: The first Ray that authenticates a local instance by default (token authentication).
RAY_MIN_VERSION = (2, 59)


def check_ray_version(version: str) -> None:
    """One-line ValueError unless ``version`` (ray.__version__) is at least RAY_MIN_VERSION."""
    parts = tuple(int(p) for p in version.split(".")[:2] if p.isdigit())
    if parts < RAY_MIN_VERSION:
        wanted = ".".join(map(str, RAY_MIN_VERSION))
        raise ValueError(f"backend='ray' needs ray>={wanted} (token authentication of its ports), found "
                         f"ray {version}: pip install 'ray>={wanted}'")


class RayBackend(Backend):
    """``pool`` Ray actors, each hosting the envs ``i`` with ``i % pool`` = its index."""

    name = "ray"

    def __init__(
        self, cfg: Any, num_envs: int, pool: int, work_dir: Path, ray_address: str | None = None
    ) -> None:
        super().__init__(cfg, num_envs, pool)
        import ray

        check_ray_version(ray.__version__)
        if not ray.is_initialized():
            ray.init(address=ray_address, include_dashboard=False, log_to_driver=False)
        self._ray = ray
        self.work_dir = Path(work_dir)
        self._actor_class = ray.remote(num_cpus=1, max_restarts=0)(EnvHost)
        self._actors: list[Any] = [None] * pool
        self._pids: list[int] = [0] * pool
        for worker in range(pool):
            self._start(worker)

    def _start(self, worker: int) -> None:
        actor = self._actor_class.remote(self.cfg, self.work_dir)
        self._actors[worker] = actor
        self._pids[worker] = self._ray.get(actor.pid.remote())

    def _send(self, worker: int, batch: list[Request]) -> Any:
        return self._actors[worker].handle_batch.remote(batch)

    def _receive(
        self, worker: int, batch: list[Request], handle: Any, deadline_s: float
    ) -> list[Reply] | None:
        exceptions = self._ray.exceptions
        try:
            return self._ray.get(handle, timeout=deadline_s)
        except exceptions.GetTimeoutError:
            self._ray.kill(self._actors[worker], no_restart=True)
        except (exceptions.RayActorError, exceptions.WorkerCrashedError):
            pass
        return None

    def _replace(self, worker: int) -> None:
        self._ray.kill(self._actors[worker], no_restart=True)
        self._start(worker)

    def worker_pid(self, env_id: int) -> int:
        return self._pids[self.worker_of(env_id)]

    def close(self) -> None:
        if not any(self._actors):
            return
        closing = [actor.close.remote() for actor in self._actors if actor is not None]
        # A dead actor has nothing left to close (its solvers are reaped by its successor): kill anyway.
        with contextlib.suppress(Exception):
            self._ray.get(closing, timeout=close_deadline_s(self.cfg, -(-self.num_envs // self.pool)))
        for worker, actor in enumerate(self._actors):
            if actor is not None:
                self._ray.kill(actor, no_restart=True)
                self._actors[worker] = None
