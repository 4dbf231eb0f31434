"""train-foam's overhead: the jitted PPO trainer + io_callback vs the same pool stepped in a plain loop.

    python benchmarks/bench_train_foam.py --mesh-scale 0.4 --updates 3 --steps-per-update 64

1. **Trainer:** the PPO trainer of train-foam (its default config, ``--steps-per-update`` env steps per
   update) trains on ``--num-envs`` cases on a ``--pool`` of workers for ``--updates`` + 1 updates. The
   first update (JAX compilation) is timed apart. Every batch step the trainer makes is recorded:
   the reset seed, the action batch, and the wall time spent inside the pool's ``step``.
2. **Plain loop:** right after each update, a second pool of the same size (reset with the same seed)
   is stepped with exactly that update's recorded actions in a Python loop. The solver is deterministic
   given seed and actions, so the same episodes run (checked: same iterations), and the
   episodes-per-hour ratio of a pair is its time ratio. Pairs are adjacent in time, so they share the
   machine's load; the median over updates is reported.

Prints one JSON object: both walls, the ratio (trainer episodes/hour over plain-loop episodes/hour,
compilation excluded) and where the trainer's time went (inside the pool's step vs PPO updates +
callback + dispatch). For benchmarks/RESULTS_train_foam.md.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from typing import Any

import jax
import numpy as np

from foam_bridge._batched import BatchedFoamEnv
from foam_bridge._config import FoamEnvConfig
from jaxsimrl.agents.ppo import PPOConfig, make_train
from jaxsimrl.apps.foam.plan import foam_ppo_defaults
from jaxsimrl.envs.host import HostVecEnv


class RecordedBatch:
    """A host batch that records its reset seed, every action batch and the time spent in step."""

    def __init__(self, batch: BatchedFoamEnv) -> None:
        self.batch = batch
        self.num_envs, self.observation_spec, self.action_spec = (
            batch.num_envs, batch.observation_spec, batch.action_spec)
        self.seed: int | None = None
        self.actions: list[np.ndarray] = []
        self.step_s: list[float] = []
        self.ended: list[dict[str, Any]] = []  # step index, env and iterations of every ended episode

    def reset(self, seed: int | None = None, options: Any = None) -> Any:
        self.seed = seed
        return self.batch.reset(seed=seed, options=options)

    def step(self, actions: np.ndarray) -> Any:
        started = time.perf_counter()
        out = self.batch.step(actions)
        self.step_s.append(time.perf_counter() - started)
        self.actions.append(np.array(actions))
        record_ended(self.ended, len(self.actions) - 1, out)
        return out


def record_ended(ended: list[dict[str, Any]], step: int, out: Any) -> None:
    terminated, truncated, infos = out[2], out[3], out[4]
    for i in np.flatnonzero(np.asarray(terminated) | np.asarray(truncated)):
        episode = infos["final_info"]["episode"]
        ended.append({"step": step, "env": int(i), "iterations": int(episode["iterations"][i])})


def paired_runs(cfg: FoamEnvConfig, ppo: PPOConfig, pool: int, updates: int) -> dict[str, Any]:
    """Trainer updates, each followed at once by the plain loop replaying that update's batch steps on a
    second pool of the same size (paused solvers use no CPU), so every pair meets the same load."""
    recorded = RecordedBatch(BatchedFoamEnv(cfg, ppo.num_envs, pool=pool, seed=0))
    plain = BatchedFoamEnv(cfg, ppo.num_envs, pool=pool, seed=0)
    pairs, plain_ended = [], []
    try:
        vec = HostVecEnv(recorded)
        trainer = make_train(ppo, vec=vec, devices=jax.devices()[:1])
        state = trainer.init(jax.random.PRNGKey(0))
        plain.reset(seed=recorded.seed)
        for _ in range(updates + 1):
            first = len(recorded.actions)
            started = time.perf_counter()
            state, metrics = trainer.run_chunk(state)
            jax.block_until_ready(metrics)
            trainer_s = time.perf_counter() - started
            started = time.perf_counter()
            for step in range(first, len(recorded.actions)):
                record_ended(plain_ended, step, plain.step(recorded.actions[step]))
            pairs.append({"trainer_s": trainer_s, "plain_s": time.perf_counter() - started,
                          "inside_pool_step_s": sum(recorded.step_s[first:])})
        vec.raise_if_failed()
    finally:
        recorded.batch.close()
        plain.close()
    return {"pairs": pairs, "same_episodes": recorded.ended == plain_ended, "ended": recorded.ended}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mesh-scale", type=float, default=0.4)
    parser.add_argument("--pool", type=int, default=2)
    parser.add_argument("--num-envs", type=int, default=2)
    parser.add_argument("--steps-per-update", type=int, default=64)
    parser.add_argument("--updates", type=int, default=3, help="timed updates (after one for compilation)")
    parser.add_argument("--out", help="also write the JSON here")
    args = parser.parse_args()
    cfg = FoamEnvConfig(mesh_scale=args.mesh_scale, simple_variant="SIMPLEC", relax_k_omega=0.8)
    ppo = PPOConfig.from_dict({**foam_ppo_defaults(args.num_envs), "steps_per_update": args.steps_per_update,
                               "total_steps": args.steps_per_update * (args.updates + 1)})
    load_before = os.getloadavg()[0]
    out = paired_runs(cfg, ppo, args.pool, args.updates)
    timed = out["pairs"][1:]  # the first update compiles
    ratios = [p["plain_s"] / p["trainer_s"] for p in timed]
    trainer_wall = sum(p["trainer_s"] for p in timed)
    result = {
        "machine": f"{platform.machine()} {os.cpu_count()} CPUs, {platform.python_version()}",
        "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()),
        "load_1min_before_after": [round(load_before, 2), round(os.getloadavg()[0], 2)],
        "mesh_scale": args.mesh_scale, "pool": args.pool, "num_envs": args.num_envs,
        "steps_per_update": args.steps_per_update, "timed_updates": args.updates,
        "same_episodes": out["same_episodes"],
        "episodes_timed": sum(e["step"] >= ppo.steps_per_env for e in out["ended"]),
        "first_update_s": out["pairs"][0]["trainer_s"],
        "pairs": timed,
        "episodes_per_hour_ratio_per_update": ratios,
        "episodes_per_hour_ratio_median": statistics.median(ratios),
        "trainer_outside_pool_step_fraction": 1 - sum(p["inside_pool_step_s"] for p in timed) / trainer_wall,
    }
    text = json.dumps(result, indent=2)
    print(text)
    if args.out:
        with open(args.out, "w") as handle:
            handle.write(text + "\n")


if __name__ == "__main__":
    main()
