"""Episodes per hour of BatchedFoamEnv on the local pool, for several pool sizes.

    python benchmarks/bench_foam_pool.py --mesh-scale 0.5 --pools 1 2 --episodes 8
    python benchmarks/bench_foam_pool.py --mesh-scale 1.0 --pools 1 2 --episodes 4 --policy constant

The same batch (``--num-envs`` cases, default 2) runs until ``--episodes`` episodes have ended in
total, with each pool size; only the number of worker processes changes. Factors are random
(uniform in the action box, seeded: the start of training) or the constant (0.95, 0.95). Prints one
markdown row per pool size plus the machine and its load, for benchmarks/RESULTS_foam_pool.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time

import numpy as np

from foam_bridge._batched import BatchedFoamEnv
from foam_bridge._config import FOLLOW_ALPHA_U, MESH_SCALE_USABLE_MIN, FoamEnvConfig


def measure(cfg: FoamEnvConfig, num_envs: int, pool: int, episodes: int, policy: str, seed: int) -> dict:
    """Run until ``episodes`` episodes ended; wall time includes worker start and case generation."""
    rng = np.random.default_rng(seed)
    low, high = np.asarray(cfg.action_low), np.asarray(cfg.action_high)
    started = time.perf_counter()
    ended: list[dict] = []
    with tempfile.TemporaryDirectory(prefix="bench_foam_pool_") as work_dir, \
            BatchedFoamEnv(cfg, num_envs, pool=pool, work_dir=work_dir, seed=seed) as env:
        env.reset()
        while len(ended) < episodes:
            if policy == "random":
                actions = rng.uniform(low, high, size=(num_envs, 2))
            else:
                actions = np.tile(high, (num_envs, 1))
            _, _, terminated, truncated, infos = env.step(actions)
            for i in np.flatnonzero(terminated | truncated):
                ended.append({"iterations": int(infos["final_info"]["iterations"][i]),
                              "outcome": str(infos["final_info"]["outcome"][i])})
    wall = time.perf_counter() - started
    iterations = [e["iterations"] for e in ended]
    return {"pool": pool, "episodes": len(ended), "wall_s": wall,
            "episodes_per_hour": 3600 * len(ended) / wall, "mean_iterations": float(np.mean(iterations)),
            "iterations_per_s": sum(iterations) / wall,
            "outcomes": {o: sum(e["outcome"] == o for e in ended) for o in {e["outcome"] for e in ended}}}


def _k_omega(text: str) -> float | str:
    """A fixed k/omega factor, or "alpha_u" (FoamEnvConfig.relax_k_omega's FOLLOW_ALPHA_U)."""
    return text if text == FOLLOW_ALPHA_U else float(text)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mesh-scale", type=float, default=MESH_SCALE_USABLE_MIN,
                        help=f"mesh resolution (default {MESH_SCALE_USABLE_MIN:g}: the usable minimum)")
    parser.add_argument("--pools", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--num-envs", type=int, default=2)
    parser.add_argument("--episodes", type=int, default=8)
    parser.add_argument("--policy", choices=("random", "constant"), default="random")
    parser.add_argument("--simple-variant", choices=("SIMPLE", "SIMPLEC"), default="SIMPLEC")
    parser.add_argument("--max-iterations", type=int, default=4000)
    parser.add_argument("--relax-k-omega", type=_k_omega, default=FOLLOW_ALPHA_U,
                        help="fixed k/omega factor (default: follow alpha_u)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    cfg = FoamEnvConfig(mesh_scale=args.mesh_scale, simple_variant=args.simple_variant,
                        max_iterations=args.max_iterations, relax_k_omega=args.relax_k_omega).validate()
    machine = platform.processor() or platform.machine()
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {machine}, {os.cpu_count()} cores, "
          f"load before {os.getloadavg()}")
    print(f"# mesh_scale={args.mesh_scale} num_envs={args.num_envs} episodes={args.episodes} "
          f"policy={args.policy} variant={args.simple_variant} relax_k_omega={args.relax_k_omega} "
          f"max_iterations={args.max_iterations} seed={args.seed}")
    print("| pool | episodes | wall s | episodes/hour | mean iterations | iterations/s | outcomes |")
    print("|---|---|---|---|---|---|---|")
    for pool in args.pools:
        r = measure(cfg, args.num_envs, pool, args.episodes, args.policy, args.seed)
        print(f"| {r['pool']} | {r['episodes']} | {r['wall_s']:.1f} | {r['episodes_per_hour']:.0f} | "
              f"{r['mean_iterations']:.0f} | {r['iterations_per_s']:.0f} | {r['outcomes']} |", flush=True)
    print(f"# load after {os.getloadavg()}")


if __name__ == "__main__":
    main()
