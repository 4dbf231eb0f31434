"""Worker step timing: what a pool-utilisation measurement sums.

    batch = AsyncFoamEnv(cfg, num_envs=4, batch_size=2, pool=2, make_env=TimedSteps())

``TimedSteps`` wraps the env a worker builds (FoamCaseEnv by default, or any ``EnvFactory``, e.g. the
stand-in solver of foam_bridge._standin) and adds ``info["step_s"]``, the seconds the worker spent in
that step: a measure that holds whatever order a batch steps its envs in (an episode's
``wall_time_s - solver_idle_s`` also counts the time its first step waits in a busy worker's queue, so
it overstates an asynchronous batch's). train-foam's asynchronous batch uses it for its
``pool_utilisation``; benchmarks/bench_async.py for both batches.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from foam_bridge._env import FoamCaseEnv

__all__ = ["TimedSteps"]


class TimedSteps:
    """An ``EnvFactory`` wrapping ``inner`` (None: FoamCaseEnv): each step's info gets "step_s"."""

    def __init__(self, inner: Any = None) -> None:
        self.inner = inner

    def __call__(self, cfg: Any, work_dir: Path, env_id: int) -> Any:
        if self.inner is None:
            env = FoamCaseEnv(cfg, work_dir=work_dir, env_id=env_id)
        else:
            env = self.inner(cfg, work_dir, env_id)
        step = env.step

        def timed_step(action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
            begun = time.monotonic()
            *result, info = step(action)
            info["step_s"] = time.monotonic() - begun
            return (*result, info)

        env.step = timed_step
        return env
