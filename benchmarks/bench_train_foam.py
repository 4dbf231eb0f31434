"""train-foam's overhead: the jitted PPO trainer + io_callback vs the same pool stepped in a plain loop.

    python benchmarks/bench_train_foam.py --mesh-scale 0.4 --updates 3 --steps-per-update 64

1. **Trainer:** the PPO trainer of train-foam (its default config, ``--steps-per-update`` env steps per
   update) trains on ``--num-envs`` cases on a ``--pool`` of workers for ``--updates`` + 1 updates. The
   first update (JAX compilation) is timed apart. Every batch step the trainer makes is recorded:
   the reset seed, the action batch, and the wall time spent inside the pool's ``step``.
2. **Plain loop:** a fresh pool of the same size is reset with the same seed and stepped with exactly
   the recorded actions in a Python loop. The solver is deterministic given seed and actions, so the
   same episodes run (checked: same iterations), and the episodes-per-hour ratio is the time ratio.

Prints one JSON object: both walls, the ratio (trainer episodes/hour over plain-loop episodes/hour,
compilation excluded) and where the trainer's time went (inside the pool's step vs PPO updates +
callback + dispatch). For benchmarks/RESULTS_train_foam.md.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from typing import Any

import jax
import numpy as np

from foam_bridge.batched import BatchedFoamEnv
from foam_bridge.config import FoamEnvConfig
from jaxsimrl.agents.ppo import PPOConfig, make_train
from jaxsimrl.cli.train_foam import foam_ppo_defaults
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


def trainer_run(cfg: FoamEnvConfig, ppo: PPOConfig, pool: int, updates: int) -> tuple[RecordedBatch, list]:
    recorded = RecordedBatch(BatchedFoamEnv(cfg, ppo.num_envs, pool=pool, seed=0))
    try:
        vec = HostVecEnv(recorded)
        trainer = make_train(ppo, vec=vec, devices=jax.devices()[:1])
        state = trainer.init(jax.random.PRNGKey(0))
        walls = []
        for _ in range(updates + 1):
            started = time.perf_counter()
            state, metrics = trainer.run_chunk(state)
            jax.block_until_ready(metrics)
            walls.append(time.perf_counter() - started)
        vec.raise_if_failed()
    finally:
        recorded.batch.close()
    return recorded, walls


def plain_run(cfg: FoamEnvConfig, recorded: RecordedBatch, pool: int) -> tuple[list[float], list]:
    times, ended = [], []
    with BatchedFoamEnv(cfg, recorded.num_envs, pool=pool, seed=0) as batch:
        batch.reset(seed=recorded.seed)
        for step, actions in enumerate(recorded.actions):
            started = time.perf_counter()
            out = batch.step(actions)
            times.append(time.perf_counter() - started)
            record_ended(ended, step, out)
    return times, ended


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
    recorded, walls = trainer_run(cfg, ppo, args.pool, args.updates)
    plain_times, plain_ended = plain_run(cfg, recorded, args.pool)
    first = ppo.steps_per_env  # batch steps of the first (compiling) update
    same = recorded.ended == plain_ended
    timed = [e for e in recorded.ended if e["step"] >= first]
    trainer_wall, plain_wall = sum(walls[1:]), sum(plain_times[first:])
    inside = sum(recorded.step_s[first:])
    result = {
        "machine": f"{platform.machine()} {os.cpu_count()} CPUs, {platform.python_version()}",
        "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()),
        "load_1min_before_after": [round(load_before, 2), round(os.getloadavg()[0], 2)],
        "mesh_scale": args.mesh_scale, "pool": args.pool, "num_envs": args.num_envs,
        "steps_per_update": args.steps_per_update, "timed_updates": args.updates,
        "same_episodes": same, "episodes_timed": len(timed),
        "first_update_s": walls[0], "trainer_wall_s": trainer_wall, "plain_wall_s": plain_wall,
        "episodes_per_hour_ratio": plain_wall / trainer_wall,
        "trainer_inside_pool_step_fraction": inside / trainer_wall,
        "trainer_outside_fraction": 1 - inside / trainer_wall,
        "mean_iterations": float(np.mean([e["iterations"] for e in timed])) if timed else None,
    }
    text = json.dumps(result, indent=2)
    print(text)
    if args.out:
        with open(args.out, "w") as handle:
            handle.write(text + "\n")


if __name__ == "__main__":
    main()
