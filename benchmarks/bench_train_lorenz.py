"""Train PPO on the Lorenz env from a JSON config and report wall time, throughput and final return.

    python benchmarks/bench_train_lorenz.py experiments/lorenz_paper.json --seed 0 --out result.json

Wall time covers everything from building the trainer to the trained parameters (compilation
included). The final return is the mean undiscounted return of the deterministic policy over
``--episodes`` full episodes from random initial states (uniform in [-40, 40]^3, fixed key), next to
the untrained policy's return from the same initial states.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import jax
import numpy as np

from jaxsimrl.agents.ppo import PPOConfig, episode_returns, make_train
from jaxsimrl.cli.errors import OneLineArgumentParser, positive_int
from jaxsimrl.envs.lorenz import Lorenz
from jaxsimrl.runs.atomic import atomic_write_json

EVAL_KEY = 12345


def run(config: PPOConfig, seed: int, episodes: int) -> dict:
    """Train once and evaluate; returns the figures of one run."""
    env = Lorenz()
    params = env.default_params()
    start = time.perf_counter()
    trainer = make_train(config, env, params)
    state = trainer.init(jax.random.PRNGKey(seed))
    initial = state
    returns_log = []
    while int(state.update_step) < trainer.num_updates:
        state, metrics = trainer.run_chunk(state)
        returns_log.extend(np.asarray(metrics["mean_episode_return"]).tolist())
    jax.block_until_ready(state.params)
    wall = time.perf_counter() - start
    eval_key = jax.random.PRNGKey(EVAL_KEY)
    final = episode_returns(trainer.policy, state, env, params, eval_key, episodes)
    before = episode_returns(trainer.policy, initial, env, params, eval_key, episodes)
    steps = trainer.num_updates * config.steps_per_update  # total_steps rounded down to whole updates
    return {"seed": seed, "wall_s": wall, "steps_per_s": steps / wall,
            "mean_return": float(final.mean()), "min_return": float(final.min()),
            "untrained_return": float(before.mean()), "train_episode_returns": returns_log}


def main() -> None:
    parser = OneLineArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config", type=Path, help="PPOConfig JSON (PPOConfig.to_dict() output)")
    parser.add_argument("--seed", type=int, nargs="+", default=[0])
    parser.add_argument("--episodes", type=positive_int, default=32)
    parser.add_argument("--out", type=Path, default=None, help="write the results as JSON here")
    args = parser.parse_args()
    try:
        config = PPOConfig.from_dict(json.loads(args.config.read_text()))
    except (OSError, ValueError) as err:  # unreadable file, bad JSON (a ValueError) or a bad config
        parser.error(f"config {args.config}: {err}")
    rows = [run(config, seed, args.episodes) for seed in args.seed]
    print(f"{'seed':>5} {'wall s':>8} {'steps/s':>9} {'return':>9} {'min':>9} {'untrained':>10}")
    for r in rows:
        print(f"{r['seed']:>5} {r['wall_s']:>8.1f} {r['steps_per_s']:>9.0f} {r['mean_return']:>9.0f} "
              f"{r['min_return']:>9.0f} {r['untrained_return']:>10.0f}")
    if len(rows) > 1:
        print(f"median wall {np.median([r['wall_s'] for r in rows]):.1f} s, "
              f"median return {np.median([r['mean_return'] for r in rows]):.0f}")
    if args.out:
        atomic_write_json(args.out, {"config": config.to_dict(), "devices": [str(d) for d in jax.devices()],
                               "runs": rows})


if __name__ == "__main__":
    main()
