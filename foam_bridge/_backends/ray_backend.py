"""The Ray backend: workers are Ray actors (one CPU each), so envs can live on any node of a cluster.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

Each actor hosts its envs exactly like a local worker (``worker.EnvHost``), with the case directories
under ``work_dir`` on the actor's own node. ``ray`` is imported only when this backend is used. If Ray
is not initialised yet, ``ray.init(address=ray_address)`` is called (``None`` starts a local instance).
An actor that dies (RayActorError) or misses the batch deadline is killed and replaced; its solvers
die with its process (PR_SET_PDEATHSIG, see foam_bridge._solver), on whatever node it ran.

A cluster loses capacity when a node dies: its actors die with it (their episodes end with cause
"node lost: IP/NODE"), and a replacement goes wherever the cluster has a free CPU, a node that
joined since included. Without one (no free CPU now, or none within ``start_deadline_s``: the
step watchdog) the worker is lost and its envs move to the surviving actors (``base``). Every wait
on Ray is bounded: an unreachable ``ray_address`` (checked with a plain TCP connect first: Ray's own
connect retries for minutes), a cluster with fewer CPUs than ``pool`` and actors that do not start
within the deadline are a one-line ``ClusterError`` at start; batches wait at most their deadline,
``close`` kills an actor that may be mid-step (``Backend.busy``) at once and waits for the others at
most ``CLOSE_GRACE_S``.

Security: Ray's processes listen on every interface. Ray >= 2.59 (RAY_MIN_VERSION, required) turns on
token authentication for a local instance started by ``ray.init()``; an older Ray would let anyone who
can reach the ports run code as this user, so it is refused. For a multi-node cluster, start every node
with ``RAY_AUTH_MODE=token`` (see docs/cluster.md).
"""

from __future__ import annotations

import os
import socket
from pathlib import Path
from typing import Any

from foam_bridge._backends.base import CLOSE_GRACE_S, WORKER_DIED, Backend, NoRoomError, start_deadline_s
from foam_bridge._backends.worker import EnvFactory, EnvHost, Reply, Request
from foam_bridge._errors import ClusterError

__all__ = ["CONNECT_TIMEOUT_S", "RAY_MIN_VERSION", "RayBackend",
           "connect"]

#: The first Ray that authenticates a local instance by default (token authentication).
RAY_MIN_VERSION = (2, 59)
#: Seconds a TCP connect to ``ray_address`` may take before the cluster counts as unreachable.
CONNECT_TIMEOUT_S = 5.0
#: Addresses that name no host:port (Ray finds the cluster itself, or starts a local one).
_NO_HOST = ("", "auto", "local")


def _check_ray_version(version: str) -> None:
    """One-line ValueError unless ``version`` (ray.__version__) is at least RAY_MIN_VERSION."""
    parts = tuple(int(p) for p in version.split(".")[:2] if p.isdigit())
    if parts < RAY_MIN_VERSION:
        wanted = ".".join(map(str, RAY_MIN_VERSION))
        raise ValueError(f"backend='ray' needs ray>={wanted} (token authentication of its ports), found "
                         f"ray {version}: pip install 'ray>={wanted}'")


def _check_reachable(address: str | None, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """One-line ClusterError unless ``address`` ("HOST:PORT" or "ray://HOST:PORT") accepts a TCP connect
    within ``timeout_s`` (``None``, "auto" and "local" are not checked: Ray resolves them itself)."""
    if address is None or address in _NO_HOST:
        return
    host, _, port = address.split("://", 1)[-1].rpartition(":")
    if not host or not port.isdigit():
        raise ClusterError(f"ray_address must be HOST:PORT (or ray://HOST:PORT, auto), got {address!r}")
    refused = _connect_error(host.strip("[]"), int(port), timeout_s)
    if refused is not None:
        raise ClusterError(f"cannot reach the Ray cluster at {address}: {refused.strerror or refused}")


def _connect_error(host: str, port: int, timeout_s: float = CONNECT_TIMEOUT_S) -> OSError | None:
    """Why ``host:port`` does not accept a TCP connect within ``timeout_s``; None if it does."""
    try:
        socket.create_connection((host, port), timeout=timeout_s).close()
    except OSError as err:
        return err
    return None


def connect(ray: Any, address: str | None) -> None:
    """``ray.init(address)`` unless Ray is initialised, failing in one line instead of retrying for long."""
    if ray.is_initialized():
        return
    _check_reachable(address)
    try:
        ray.init(address=address, include_dashboard=False, log_to_driver=False)
    except ConnectionError as err:
        raise ClusterError(f"cannot connect to the Ray cluster at {address}: "
                           f"{str(err).splitlines()[0] if str(err) else type(err).__name__}") from None


class _RayHost(EnvHost):
    """EnvHost as a Ray actor: it also says where it runs."""

    def where(self) -> tuple[int, str, str]:
        """(process id, node id, node label "IP/NODE8" as episodes.csv records it)."""
        import ray

        node_id = ray.get_runtime_context().get_node_id()
        return os.getpid(), node_id, f"{ray.util.get_node_ip_address()}/{node_id[:8]}"


class RayBackend(Backend):
    """``pool`` Ray actors, each hosting the envs ``i`` with ``i % pool`` = its index."""

    name = "ray"

    def __init__(
        self, cfg: Any, num_envs: int, pool: int, work_dir: Path, ray_address: str | None = None,
        make_env: EnvFactory | None = None,
    ) -> None:
        super().__init__(cfg, num_envs, pool)
        self._make_env = make_env
        import ray

        _check_ray_version(ray.__version__)
        connect(ray, ray_address)
        self._ray = ray
        self.work_dir = Path(work_dir)
        self._actor_class = ray.remote(num_cpus=1, max_restarts=0)(_RayHost)
        self._actors: list[Any] = [None] * pool
        self._pids: list[int] = [0] * pool
        self._nodes: list[tuple[str, str]] = [("", "")] * pool  # (node id, label) per worker
        self._lost_nodes: set[str] = set()
        cpus = ray.cluster_resources().get("CPU", 0.0)
        if cpus < pool:
            raise ClusterError(f"the Ray cluster has {cpus:g} CPUs; a pool of {pool} workers needs {pool} "
                               f"(one CPU each)")
        try:
            self._start(list(range(pool)))
        except NoRoomError as err:
            raise ClusterError(f"cannot start {pool} Ray workers: {err}") from None

    def _start(self, workers: list[int]) -> None:
        """Start actors for ``workers`` and wait (bounded) until each runs; NoRoomError if not."""
        actors = [self._actor_class.remote(self.cfg, self.work_dir, self._make_env) for _ in workers]
        deadline = start_deadline_s(self.cfg)
        try:
            started = self._ray.get([actor.where.remote() for actor in actors], timeout=deadline)
        except self._ray.exceptions.GetTimeoutError:
            for actor in actors:  # also cancels a creation still waiting for a CPU
                self._ray.kill(actor, no_restart=True)
            free = self._ray.available_resources().get("CPU", 0.0)
            raise NoRoomError(f"no Ray actor started within {deadline:.0f} s ({free:g} CPUs free)") from None
        for worker, actor, (pid, node_id, label) in zip(workers, actors, started, strict=True):
            self._actors[worker], self._pids[worker], self._nodes[worker] = actor, pid, (node_id, label)

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

    def _wait_ready(self, workers: list[int], timeout_s: float) -> list[int]:
        """The workers whose oldest submitted batch is done (a dead actor's is done, with an error)."""
        heads = {self._queues[worker][0][1]: worker for worker in workers}
        done, _ = self._ray.wait(list(heads), num_returns=1, timeout=timeout_s)
        done += self._ray.wait(list(heads), num_returns=len(heads), timeout=0)[0]
        return sorted({heads[ref] for ref in done})

    def _death_cause(self, worker: int) -> str:
        """"node lost: IP/NODE" when the actor's node is gone, else "worker died"."""
        node_id, label = self._nodes[worker]
        if self._node_gone(node_id):
            self._lost_nodes.add(node_id)
            return f"node lost: {label}"
        return WORKER_DIED

    def _node_gone(self, node_id: str) -> bool:
        """Whether a node is dead for the GCS or its raylet refuses connections: the GCS declares a node
        dead only once its health checks have failed for a while, after its actors are seen dead."""
        for node in self._alive_nodes():
            if node["NodeID"] == node_id:
                return _connect_error(node["NodeManagerAddress"], int(node["NodeManagerPort"])) is not None
        return True

    def _alive_nodes(self) -> list[dict[str, Any]]:
        """The nodes the GCS counts as alive, less those this backend found lost."""
        try:
            nodes = self._ray.nodes()
        except Exception:  # noqa: BLE001 - the GCS itself is unreachable: no node counts as alive
            return []
        return [node for node in nodes if node.get("Alive") and node["NodeID"] not in self._lost_nodes]

    def _replace(self, worker: int) -> None:
        self._ray.kill(self._actors[worker], no_restart=True)
        cpus = sum(node.get("Resources", {}).get("CPU", 0.0) for node in self._alive_nodes())
        if cpus < self.workers():  # the live actors (this one's replacement included) take one CPU each
            raise NoRoomError(f"no free CPU for a replacement: {cpus:g} on the nodes alive, "
                              f"{self.workers() - 1} taken by the other workers")
        self._start([worker])

    def worker_pid(self, env_id: int) -> int:
        return self._pids[self.worker_of(env_id)]

    def node_of(self, env_id: int) -> str:
        return self._nodes[self.worker_of(env_id)][1]

    def close(self) -> None:
        live = [(worker, actor) for worker, actor in enumerate(self._actors) if actor is not None]
        if not live:
            return
        # an actor mid-step would answer close only after its step (minutes on a big mesh): killed now
        # below; the idle ones close their envs (a dead one answers at once) within the grace
        busy = self._forget_busy()
        closing = [actor.close.remote() for worker, actor in live if worker not in busy]
        if closing:
            self._ray.wait(closing, num_returns=len(closing), timeout=CLOSE_GRACE_S)
        for worker, actor in live:
            self._ray.kill(actor, no_restart=True)
            self._actors[worker] = None
