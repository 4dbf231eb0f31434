"""Throughput of the pure-JAX Lorenz env: environment steps per second at several batch sizes.

Each measurement runs ``--steps`` steps of ``num_envs`` envs as one jitted ``lax.scan`` over a
``vmap``-ed step, with actions drawn uniformly in the action box inside the scan (``--actions zero``
drops the random draws, to separate the env's own cost from the PRNG's). Compilation is timed apart
(``compile_s``), then the compiled function runs ``--repeats`` times from the same random initial
states with fresh keys; the median wall time gives steps/s. Episodes are 4000 steps and the env never
auto-resets, so keep ``--steps`` <= 4000 for a measurement made of in-episode steps only.

    python benchmarks/bench_env.py --num-envs 1,64,1024,8192 --steps 1000 --repeats 7 --out bench_env.json
"""

from __future__ import annotations

import argparse
import datetime as dt
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp

from jaxsimrl.cli.errors import OneLineArgumentParser, positive_int
from jaxsimrl.envs.lorenz import Lorenz, LorenzParams, LorenzState
from jaxsimrl.runs.atomic import atomic_write_json


def make_rollout(env: Lorenz, params: LorenzParams, num_envs: int, steps: int, actions: str,
                 unroll: int) -> Callable[[jax.Array, LorenzState], tuple[LorenzState, jax.Array]]:
    """A function (key, states) -> (final states, summed rewards) running ``steps`` batched steps."""
    space = env.action_space(params)
    step = jax.vmap(env.step, in_axes=(None, 0, 0, None))

    def body(carry, key):
        states, total = carry
        if actions == "uniform":
            action = jax.random.uniform(key, (num_envs, env.action_dim), minval=space.low, maxval=space.high)
        else:
            action = jnp.zeros((num_envs, env.action_dim))
        out = step(key, states, action, params)
        return (out.state, total + out.reward), None

    def rollout(key: jax.Array, states: LorenzState) -> tuple[LorenzState, jax.Array]:
        # The summed reward keeps every step live: nothing can be dead-code eliminated.
        (states, total), _ = jax.lax.scan(body, (states, jnp.zeros(num_envs)), jax.random.split(key, steps),
                                          unroll=unroll)
        return states, total

    return rollout


def measure(num_envs: int, steps: int, repeats: int, seed: int, actions: str, unroll: int) -> dict[str, Any]:
    """Compile once, then time ``repeats`` runs; returns the figures for one batch size."""
    env, params = Lorenz(), LorenzParams()
    key = jax.random.key(seed)
    init_keys = jax.random.split(jax.random.fold_in(key, num_envs), num_envs)
    _, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(init_keys, params)
    rollout = jax.jit(make_rollout(env, params, num_envs, steps, actions, unroll))

    start = time.perf_counter()
    compiled = rollout.lower(key, states).compile()
    compile_s = time.perf_counter() - start
    start = time.perf_counter()
    jax.block_until_ready(compiled(key, states))
    first_run_s = time.perf_counter() - start

    times = []
    for i in range(repeats):
        run_key = jax.random.fold_in(key, i + 1)
        start = time.perf_counter()
        _, total = jax.block_until_ready(compiled(run_key, states))
        times.append(time.perf_counter() - start)
    median = statistics.median(times)
    return {
        "num_envs": num_envs, "steps": steps, "repeats": repeats, "compile_s": compile_s,
        "first_run_s": first_run_s, "times_s": times, "median_s": median,
        "steps_per_s": num_envs * steps / median, "steps_per_s_best": num_envs * steps / min(times),
        "mean_step_reward": float(total.mean()) / steps,
    }


def measure_gym(steps: int, repeats: int, seed: int) -> dict[str, Any]:
    """Steps/s of the single-env gymnasium wrapper (a Python loop: one jitted call per step)."""
    from jaxsimrl.envs.gym_lorenz import LorenzGymEnv  # only this measurement needs gymnasium

    env = LorenzGymEnv()
    env.reset(seed=seed)
    env.step(env.action_space.sample())  # compile
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(steps):
            env.step(env.action_space.sample())
        times.append(time.perf_counter() - start)
    median = statistics.median(times)
    return {"steps": steps, "repeats": repeats, "times_s": times, "median_s": median,
            "steps_per_s": steps / median}


def machine() -> dict[str, Any]:
    device = jax.devices()[0]
    return {
        "date_utc": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "jax": jax.__version__, "backend": jax.default_backend(), "device": device.device_kind,
        "device_count": jax.device_count(), "cpu_count": os.cpu_count(), "python": platform.python_version(),
        "processor": platform.processor() or platform.machine(),
        "load_average_1_5_15": list(os.getloadavg()),
    }


def format_table(rows: list[dict[str, Any]]) -> str:
    lines = [f"{'envs':>6} {'steps':>6} {'compile s':>10} {'median s':>9} {'steps/s (median)':>17} "
             f"{'steps/s (best)':>15}"]
    for r in rows:
        lines.append(f"{r['num_envs']:>6} {r['steps']:>6} {r['compile_s']:>10.2f} {r['median_s']:>9.4f} "
                     f"{r['steps_per_s']:>17.3e} {r['steps_per_s_best']:>15.3e}")
    return "\n".join(lines)


def _positive_int_list(text: str) -> list[int]:
    return [positive_int(v) for v in text.split(",")]


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = OneLineArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--num-envs", type=_positive_int_list, default=[1, 64, 1024, 8192],
                        help="comma-separated batch sizes (default 1,64,1024,8192)")
    parser.add_argument("--steps", type=positive_int, default=1000, help="scan length per run (default 1000)")
    parser.add_argument("--repeats", type=positive_int, default=7,
                        help="timed runs per size, >= 5 (default 7)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--actions", choices=("uniform", "zero"), default="uniform",
                        help="uniform random actions in the box (default) or zero actions (no PRNG cost)")
    parser.add_argument("--unroll", type=positive_int, default=1, help="lax.scan unroll factor (default 1)")
    parser.add_argument("--gym-steps", type=int, default=0,
                        help="also time the gymnasium wrapper over this many steps per run (default 0: skip)")
    parser.add_argument("--out", help="write the results as JSON to this file")
    args = parser.parse_args(argv)
    if args.repeats < 5:
        parser.error(f"--repeats must be >= 5 for a meaningful median, got {args.repeats}")
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    rows = [measure(n, args.steps, args.repeats, args.seed, args.actions, args.unroll) for n in args.num_envs]
    print(format_table(rows))
    gym = measure_gym(args.gym_steps, args.repeats, args.seed) if args.gym_steps > 0 else None
    if gym:
        print(f"gymnasium wrapper, 1 env, Python loop: {gym['steps_per_s']:.3e} steps/s (median)")
    if args.out:
        result = {"benchmark": "lorenz_env_steps", "actions": args.actions, "unroll": args.unroll,
                  "machine": machine(), "results": rows, "gym_wrapper": gym}
        atomic_write_json(args.out, result)
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
