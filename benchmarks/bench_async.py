"""Solver utilisation of a foam env batch vs pool size, lock-step or asynchronous, on the stand-in solver.

    python benchmarks/bench_async.py --mode lockstep --workers 2 8 32 128 --out benchmarks/async.json
    python benchmarks/bench_async.py --mode async --workers 2 8 32 128 --out benchmarks/async.json
    python benchmarks/bench_async.py --mode lockstep --workers 2 --solver real --window-s 600 ...

Each configuration drives a batch with random actions (no learner: the trainer's own share is 0.12 %,
RESULTS_train_foam.md) for ``--warmup-s`` and then a ``--window-s`` window. Utilisation is busy time
over ``pool x window``, three ways:

- ``steps``: the worker seconds of every step whose result came back in the window (each env is wrapped
  in foam_bridge._timing.TimedSteps); the measure for both batches and both solvers.
- ``records``: wall_time_s - solver_idle_s of the episodes that ended in the window (what train-foam's
  pool_utilisation counts; counting episodes by their end, in a steady state, neither loses nor
  double-counts the ones that straddle the window's edges). It also counts the time an episode's first
  step waits in a busy worker's queue, so it overstates the asynchronous batch's utilisation.
- ``exact``: solver_time_s of those episodes: for the stand-in the seconds it slept computing, for the
  real solver its CPU seconds (lower than its wall time on a loaded machine).

``--simulate`` instead runs a discrete-event model of both batches on the same profile (no processes,
no sleeps, zero host latency): the utilisation the batch's shape alone allows, to hold the measured
numbers against (a shortfall is this machine's latency, not the batch).

Results are merged into ``--out`` (JSON, keyed by mode, solver, profile and pool), written atomically.

Lock-step: ``num_envs = pool`` (as train-foam runs). Async: ``num_envs = --envs-per-worker x pool`` and
``batch_size = pool`` (foam_bridge._async_batch).
"""

from __future__ import annotations

import argparse
import heapq
import json
import os
import platform
import resource
import sys
import time
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from atomicfile import atomic_write_text  # noqa: E402
from foam_bridge._config import FoamEnvConfig  # noqa: E402
from foam_bridge._standin import DETREND, Profile, StandIn  # noqa: E402
from foam_bridge._timing import TimedSteps  # noqa: E402

PROFILES = {"mesh05": ("experiments/foam/train-mesh05/episodes.csv", 757),  # RESULTS_train_foam's 757
            "full": ("experiments/foam/finetune-full/episodes.csv", None)}


def _records(infos: dict[str, Any], rows: list[int]) -> list[dict[str, Any]]:
    """The episode records of the envs (row positions) whose episode ended in this result."""
    mask = infos.get("_final_info")
    if mask is None:
        return []
    episode = infos["final_info"]["episode"]
    return [{key: value[r] for key, value in episode.items() if not key.startswith("_")
             and not isinstance(value, dict)} for r in rows if mask[r]]


def _step_seconds(infos: dict[str, Any]) -> float:
    """Worker seconds of the steps in this result (TimedSteps' "step_s"; an ended episode's last step
    is in its final info)."""
    total = 0.0
    for where in (infos, infos.get("final_info", {})):
        if "step_s" in where:
            total += float(np.sum(np.asarray(where["step_s"], float)[np.asarray(where["_step_s"], bool)]))
    return total


def _worker_rss_mib(pids: list[int]) -> float:
    total = 0
    for pid in set(pids):
        try:
            with open(f"/proc/{pid}/status") as handle:
                total += next(int(line.split()[1]) for line in handle if line.startswith("VmRSS"))
        except (OSError, StopIteration):
            pass
    return total / 1024


def _actions(rng: np.random.Generator, batch: Any, rows: int, fixed: list[float] | None) -> np.ndarray:
    """Random factors in the action box, or ``fixed`` ones for every row."""
    low, high = batch.action_spec.low, batch.action_spec.high
    return np.tile(fixed, (rows, 1)) if fixed else rng.uniform(low, high, (rows, len(low)))


def _drive_lockstep(batch: Any, until: float, ended: list, fixed: list[float] | None) -> int:
    batch.reset(seed=0)
    rng, steps = np.random.default_rng(0), 0
    while time.monotonic() < until:
        actions = _actions(rng, batch, batch.num_envs, fixed)
        *_, infos = batch.step(actions)
        now = time.monotonic()
        ended += [(now, rec) for rec in _records(infos, list(range(batch.num_envs)))]
        ended.append((now, {"step_s": _step_seconds(infos)}))
        steps += batch.num_envs
    return steps


def _drive_async(batch: Any, until: float, ended: list, fixed: list[float] | None) -> int:
    batch.async_reset(seed=0)
    rng, steps = np.random.default_rng(0), 0
    while time.monotonic() < until:
        ids, _, _, _, _, infos = batch.recv()
        now = time.monotonic()
        ended += [(now, rec) for rec in _records(infos, list(range(len(ids))))]
        ended.append((now, {"step_s": _step_seconds(infos)}))
        batch.send(_actions(rng, batch, len(ids), fixed), ids)
        steps += len(ids)
    return steps


def measure(mode: str, pool: int, cfg: FoamEnvConfig, make_env: Any, warmup_s: float, window_s: float,
            envs_per_worker: int, batch_fraction: float, fixed: list[float] | None = None) -> dict[str, Any]:
    """One configuration's utilisation (see the module docstring)."""
    from foam_bridge._batched import BatchedFoamEnv

    started = time.monotonic()
    if mode == "lockstep":
        batch = BatchedFoamEnv(cfg, num_envs=pool, pool=pool, seed=0, make_env=make_env)
        drive = _drive_lockstep
    else:
        from foam_bridge._async_batch import AsyncFoamEnv

        batch = AsyncFoamEnv(cfg, num_envs=envs_per_worker * pool, pool=pool, seed=0, make_env=make_env,
                             batch_size=max(1, round(batch_fraction * pool)))
        drive = _drive_async
    ended: list[tuple[float, dict[str, Any]]] = []
    with batch:
        setup_s = time.monotonic() - started
        t0 = time.monotonic()
        steps = drive(batch, t0 + warmup_s + window_s, ended, fixed)
        t1 = time.monotonic()
        rss = _worker_rss_mib(batch.worker_pids())
    stepped = sum(rec["step_s"] for at, rec in ended if at >= t0 + warmup_s and "step_s" in rec)
    window = [rec for at, rec in ended if at >= t0 + warmup_s and "step_s" not in rec]
    span = t1 - (t0 + warmup_s)
    records = sum(max(r["wall_time_s"] - r["solver_idle_s"], 0.0) for r in window)
    exact = sum(r["solver_time_s"] for r in window)
    return {"mode": mode, "pool": pool, "num_envs": batch.num_envs,
            "batch_size": getattr(batch, "batch_size", batch.num_envs), "episodes": len(window),
            "window_s": span, "env_steps_per_s": steps / (t1 - t0), "setup_s": setup_s,
            "workers_rss_mib": rss, "utilisation_steps": stepped / (pool * span),
            "utilisation_records": records / (pool * span),
            "utilisation_exact": exact / (pool * span) if np.isfinite(exact) else None,
            "mean_iterations": float(np.mean([r["iterations"] for r in window])) if window else None}


def simulate(profile: Profile, pool: int, envs_per_worker: int, batch_size: int, seconds: float = 3000.0,
             seed: int = 0) -> float:
    """Utilisation of a batch of ``pool x envs_per_worker`` envs that hands the learner ``batch_size``
    ready envs at a time (1 env per worker and batch_size = pool: lock-step), with no host latency."""
    rng, envs = np.random.default_rng(seed), pool * envs_per_worker
    left, rate = [0] * envs, [0.0] * envs
    queues: list[deque] = [deque() for _ in range(pool)]
    free_at, events, ready, busy, now = [0.0] * pool, [], list(range(envs)), 0.0, 0.0
    for env in range(envs):
        left[env], rate[env] = profile.draw(rng)

    def start(worker: int) -> None:
        nonlocal busy
        if free_at[worker] > now or not queues[worker]:
            return
        env, kind = queues[worker].popleft()
        took = profile.reset_s * profile.time_scale
        if kind == "step":
            run = min(profile.interval, left[env])
            left[env], took = left[env] - run, run * rate[env]
            busy += took
        free_at[worker] = now + took
        heapq.heappush(events, (now + took, worker, env, kind))

    while now < seconds:
        while len(ready) >= batch_size:
            taken, ready[:] = ready[:batch_size], ready[batch_size:]
            for env in taken:
                queues[env % pool].append((env, "step"))
            for worker in {env % pool for env in taken}:
                start(worker)
        now, worker, env, kind = heapq.heappop(events)
        if kind == "step" and left[env] == 0:  # episode over: its reset goes first, then it is ready
            left[env], rate[env] = profile.draw(rng)
            queues[worker].appendleft((env, "reset"))
        else:
            ready.append(env)
        start(worker)
    return busy / (pool * now)


def _simulate_all(args: argparse.Namespace, profile: Profile) -> int:
    for pool in args.workers:
        per_worker, size = (1, pool) if args.mode == "lockstep" else \
            (args.envs_per_worker, max(1, round(args.batch_fraction * pool)))
        print(json.dumps({"mode": args.mode, "pool": pool, "num_envs": pool * per_worker, "batch_size": size,
                          "simulated_utilisation": simulate(profile, pool, per_worker, size)}), flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mode", choices=("lockstep", "async"), default="lockstep")
    parser.add_argument("--workers", type=int, nargs="+", default=[2, 8, 32, 128])
    parser.add_argument("--solver", choices=("standin", "real"), default="standin")
    parser.add_argument("--profile", choices=tuple(PROFILES), default="mesh05")
    parser.add_argument("--time-scale", type=float, default=1.0)
    parser.add_argument("--detrend", type=int, default=DETREND, help="standin.Profile.from_csv's window")
    parser.add_argument("--mesh-scale", type=float, default=0.5)
    parser.add_argument("--warmup-s", type=float, default=20.0)
    parser.add_argument("--window-s", type=float, default=120.0)
    parser.add_argument("--envs-per-worker", type=int, default=2)
    parser.add_argument("--batch-fraction", type=float, default=1.0, help="async batch_size / pool")
    parser.add_argument("--fixed-action", type=float, nargs="+", default=None,
                        help="these factors in every step instead of random ones (the real solver's "
                             "episodes are then as short as a trained policy's)")
    parser.add_argument("--simulate", action="store_true", help="the discrete-event model instead")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    if min(args.workers) < 1 or min(args.time_scale, args.window_s, args.envs_per_worker) <= 0 \
            or not 0 < args.batch_fraction <= args.envs_per_worker:
        print("bench_async: --workers, --time-scale, --window-s, --envs-per-worker must be > 0 and "
              "--batch-fraction in (0, envs-per-worker]", file=sys.stderr)
        return 2
    if args.simulate and args.solver != "standin":
        print("bench_async: --simulate models the stand-in's profile: drop --solver real", file=sys.stderr)
        return 2
    cfg = FoamEnvConfig(mesh_scale=args.mesh_scale)
    standin = None
    if args.solver == "standin":
        path, first = PROFILES[args.profile]
        standin = StandIn(Profile.from_csv(ROOT / path, first, time_scale=args.time_scale,
                                           detrend=args.detrend))
        print(f"profile {args.profile}: {standin.profile.describe()}", flush=True)
    make_env = TimedSteps(standin)
    if args.simulate:
        return _simulate_all(args, standin.profile)
    results = json.loads(args.out.read_text()) if args.out and args.out.exists() else {}
    for pool in args.workers:
        row = measure(args.mode, pool, cfg, make_env, args.warmup_s, args.window_s, args.envs_per_worker,
                      args.batch_fraction, args.fixed_action)
        row.update(fixed_action=args.fixed_action, solver=args.solver, detrend=args.detrend,
                   profile=args.profile if standin else None, time_scale=args.time_scale,
                   load_1min=os.getloadavg()[0], host=platform.node(), cpus=os.cpu_count(),
                   driver_max_rss_mib=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                   date_utc=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()))
        print(json.dumps(row), flush=True)
        setup = f"{args.profile}-d{args.detrend}" if standin else f"mesh{args.mesh_scale}"
        shape = "" if args.mode == "lockstep" else f"/x{args.envs_per_worker}b{args.batch_fraction:g}"
        key = f"{args.mode}{shape}/{args.solver}/{setup}/{pool}"
        results[key] = row
        if args.out:
            atomic_write_text(args.out, json.dumps(results, indent=1, sort_keys=True) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
