"""The local backend: a pool of worker processes on this machine (multiprocessing, "spawn" context).

"spawn" (not fork) so a parent that has already initialised JAX or threads is safe. Each worker serves
batches of requests over a pipe until it gets ``None`` or the pipe closes (the driver died); either
way it closes its envs, so their solvers die with it. A worker that dies is noticed through its
process sentinel and replaced (see ``base``).
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import signal
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

from foam_bridge.backends.base import Backend
from foam_bridge.backends.worker import EnvHost, Reply, Request

JOIN_TIMEOUT_S = 30.0


def preflight(cfg: Any) -> None:
    """Fail now, in one line, on what would fail every env later: no OpenFOAM, a broken user case.

    Only for the local backend: Ray nodes may have OpenFOAM and the case where the driver has not.
    """
    from foam_bridge.case import check_case_files
    from foam_bridge.openfoam import find_openfoam

    find_openfoam(cfg.openfoam_path)
    if cfg.case_dir is not None:
        check_case_files(Path(cfg.case_dir), cfg, need_mesh=False)


def _serve(conn: Connection, cfg: Any, work_dir: Path) -> None:
    """Worker main loop."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the driver's to handle; it closes us
    host = EnvHost(cfg, work_dir)
    try:
        while True:
            try:
                batch = conn.recv()
            except (EOFError, OSError):
                break
            if batch is None:
                break
            conn.send(host.handle_batch(batch))
    finally:
        host.close()


class LocalBackend(Backend):
    """``pool`` spawned processes on this machine; worker ``w`` hosts the envs with ``i % pool == w``."""

    name = "local"

    def __init__(self, cfg: Any, num_envs: int, pool: int, work_dir: Path) -> None:
        super().__init__(cfg, num_envs, pool)
        preflight(cfg)
        self.work_dir = Path(work_dir)
        self._ctx = mp.get_context("spawn")
        self._procs: list[Any] = [None] * pool
        self._conns: list[Connection | None] = [None] * pool
        for worker in range(pool):
            self._start(worker)

    def _start(self, worker: int) -> None:
        parent_end, child_end = self._ctx.Pipe()
        proc = self._ctx.Process(
            target=_serve, args=(child_end, self.cfg, self.work_dir), name=f"foam-worker-{worker}",
            daemon=True,
        )
        proc.start()
        child_end.close()
        self._procs[worker], self._conns[worker] = proc, parent_end

    def _send(self, worker: int, batch: list[Request]) -> bool:
        try:
            self._conns[worker].send(batch)
            return True
        except (BrokenPipeError, OSError):
            return False

    def _receive(
        self, worker: int, batch: list[Request], handle: Any, deadline_s: float
    ) -> list[Reply] | None:
        conn, proc = self._conns[worker], self._procs[worker]
        if not handle:
            return None
        ready = wait([conn, proc.sentinel], timeout=deadline_s)
        if conn in ready:
            try:
                return conn.recv()
            except (EOFError, OSError):
                return None
        if not ready:  # missed the deadline: a hung worker counts as a dead one
            proc.kill()
        return None

    def _replace(self, worker: int) -> None:
        proc, conn = self._procs[worker], self._conns[worker]
        proc.kill()
        proc.join(JOIN_TIMEOUT_S)
        conn.close()
        self._start(worker)

    def worker_pid(self, env_id: int) -> int:
        return self._procs[self.worker_of(env_id)].pid

    def close(self) -> None:
        live = [(w, conn) for w, conn in enumerate(self._conns) if conn is not None]
        for _, conn in live:  # ask every worker first, so they close their envs in parallel
            with contextlib.suppress(BrokenPipeError, OSError):
                conn.send(None)
        for worker, conn in live:
            proc = self._procs[worker]
            proc.join(JOIN_TIMEOUT_S)
            if proc.is_alive():
                proc.kill()
                proc.join(JOIN_TIMEOUT_S)
            conn.close()
            self._conns[worker] = None
