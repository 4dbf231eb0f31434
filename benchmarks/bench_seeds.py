"""One seed alone vs N seeds in one jitted call (SeedBatch): wall time, throughput and FLOP rate.

    python benchmarks/bench_seeds.py --agents 16 --updates 3 --repeats 3 --out seeds.json

Both trainers run the same config (default: PPOConfig(), the paper config: 2 envs x 4000 steps, 2 x 64
tanh + LSTM 256) for ``--updates`` updates per timed call, from the same initial states each repeat; the
first call of each compiles and is not timed, and the repeats alternate between them so that a change of
machine load hits all. For reference, one agent with N x the envs and N x the steps per update (the
batch's data through one network, as large matmuls) is timed too (``--no-wide`` skips it). Reported:
median wall time of each, the batch's ratio to one seed (the target: N seeds in at most N/2 times one
seed's time), env steps/s, and the FLOP rate against this machine's measured float32 matmul peak (the
fastest median of a jitted ``jnp.dot`` of two square matrices over ``--matmul-sizes``).

FLOPs: XLA's ``compiled.cost_analysis()['flops']`` counts the body of a loop once, whatever its trip count
(a scan of ten matmuls reports one), and an update is nearly all loops (4000 rollout steps, epochs,
minibatches, LSTM time steps). So the rate uses the matmul FLOPs of the update's jaxpr with every scan
multiplied by its length (``jaxpr_matmul_flops``: 2 x M x N x K per dot_general); XLA's raw figure is
reported next to it.
"""

from __future__ import annotations

import dataclasses
import json
import os
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.extend import core as jcore

from jaxsimrl.agents.ppo import PPOConfig, SeedBatch, make_train
from jaxsimrl.agents.ppo.batch import seed_keys
from jaxsimrl.cli.errors import OneLineArgumentParser, positive_int
from jaxsimrl.runs.atomic import atomic_write_json


# ---- FLOP counting -------------------------------------------------------------------------------------
def _subjaxprs(eqn: Any) -> list[Any]:
    """The jaxprs inside an equation's parameters (pjit, shard_map, custom_vjp, remat, ...)."""
    found = []
    for value in eqn.params.values():
        for item in value if isinstance(value, tuple | list) else (value,):
            if isinstance(item, jcore.ClosedJaxpr):
                found.append(item.jaxpr)
            elif isinstance(item, jcore.Jaxpr):
                found.append(item)
    return found


def _dot_flops(eqn: Any) -> int:
    (lhs_contract, _), _ = eqn.params["dimension_numbers"]
    lhs = eqn.invars[0].aval.shape
    return 2 * int(np.prod(eqn.outvars[0].aval.shape)) * int(np.prod([lhs[i] for i in lhs_contract]))


def _eqn_flops(eqn: Any) -> int:
    name = eqn.primitive.name
    if name == "dot_general":
        return _dot_flops(eqn)
    inner = [jaxpr_matmul_flops(sub) for sub in _subjaxprs(eqn)]
    if name == "scan":
        return eqn.params["length"] * sum(inner)
    if name == "cond":  # the branch taken is not known here: the most expensive one (PPO: the update)
        return max(inner, default=0)
    if name == "while":
        raise ValueError("a while loop with an unknown trip count: its FLOPs cannot be counted")
    if name == "shard_map":  # the body sees one device's share
        return eqn.params["mesh"].size * sum(inner)
    return sum(inner)


def jaxpr_matmul_flops(jaxpr: Any) -> int:
    """Matmul FLOPs (2 x M x N x K per dot_general, batch dims included) of ``jaxpr`` as executed: the body
    of a scan counted ``length`` times, a cond by its costliest branch."""
    jaxpr = jaxpr.jaxpr if isinstance(jaxpr, jcore.ClosedJaxpr) else jaxpr
    return sum(_eqn_flops(eqn) for eqn in jaxpr.eqns)


# ---- timing ------------------------------------------------------------------------------------------
def matmul_peak(size: int, repeats: int) -> float:
    """Median FLOP/s of a jitted float32 ``jnp.dot`` of two ``size`` x ``size`` matrices."""
    a = jax.random.normal(jax.random.PRNGKey(0), (size, size), jnp.float32)
    b = jax.random.normal(jax.random.PRNGKey(1), (size, size), jnp.float32)
    dot = jax.jit(jnp.dot)
    dot(a, b).block_until_ready()
    return 2 * size**3 / statistics.median(_time(lambda: dot(a, b)) for _ in range(repeats))


def matmul_peaks(sizes: list[int], repeats: int) -> dict[int, float]:
    """{size: FLOP/s} of :func:`matmul_peak` for each size."""
    return {size: matmul_peak(size, repeats) for size in sizes}


def _time(call: Callable[[], Any]) -> float:
    start = time.perf_counter()
    jax.block_until_ready(call())
    return time.perf_counter() - start


@dataclasses.dataclass
class Case:
    """One trainer (a single seed or a batch) with its initial state and its compiled chunk."""

    name: str
    env_steps: int  # env steps per call, all agents together
    run: Callable[[], Any]
    compile_s: float
    xla_flops: float
    matmul_flops: int
    times: list[float] = dataclasses.field(default_factory=list)


def _case(name: str, env_steps: int, jitted: Any, state: Any) -> Case:
    start = time.perf_counter()
    compiled = jitted.lower(state).compile()
    compile_s = time.perf_counter() - start
    jax.block_until_ready(compiled(state))  # first run (allocations, thread pools) is not timed
    costs = compiled.cost_analysis()
    costs = costs[0] if isinstance(costs, list) else costs
    return Case(name, env_steps, lambda: compiled(state), compile_s, float(costs.get("flops", 0.0)),
                jaxpr_matmul_flops(jax.make_jaxpr(jitted)(state)))


def _for_updates(config: PPOConfig, updates: int, widen: int = 1) -> PPOConfig:
    """``config`` running ``updates`` updates in one chunk, with ``widen`` times the envs and data."""
    return dataclasses.replace(config, num_envs=widen * config.num_envs, updates_per_chunk=updates,
                               steps_per_update=widen * config.steps_per_update,
                               total_steps=updates * widen * config.steps_per_update)


def build_cases(config: PPOConfig, agents: int, updates: int, wide: bool) -> list[Case]:
    """The one-seed trainer (seed 0), an ``agents`` batch (seeds 0..agents-1) and, if ``wide``, one agent
    with ``agents`` times the envs and steps per update (the same data as the batch through one network),
    each running ``updates`` updates per call."""
    single = _for_updates(config, updates)
    trainer, steps = make_train(single), updates * single.steps_per_update
    batch = SeedBatch(trainer, agents)
    # The jitted chunks are private; the benchmark needs them to compile and count their FLOPs.
    cases = [_case("1 seed", steps, trainer._chunk, trainer.init(jax.random.PRNGKey(0))),
             _case(f"{agents} seeds", agents * steps, batch._chunk_jit, batch.init(seed_keys(range(agents))))]
    if wide:
        widened = make_train(_for_updates(config, updates, agents))
        cases.append(_case(f"{agents}x envs", agents * steps, widened._chunk,
                           widened.init(jax.random.PRNGKey(0))))
    return cases


def summarise(case: Case, peak: float) -> dict[str, Any]:
    wall = statistics.median(case.times)
    rate = case.matmul_flops / wall
    return {"name": case.name, "compile_s": case.compile_s, "times_s": case.times, "median_s": wall,
            "env_steps_per_s": case.env_steps / wall, "matmul_flops": case.matmul_flops,
            "xla_cost_analysis_flops": case.xla_flops, "matmul_flops_per_s": rate,
            "fraction_of_peak": rate / peak}


def measure(config: PPOConfig, agents: int, updates: int, repeats: int, matmul_sizes: list[int],
            wide: bool = True) -> dict[str, Any]:
    load_before = os.getloadavg()
    peaks = matmul_peaks(matmul_sizes, max(repeats, 5))
    peak = max(peaks.values())
    cases = build_cases(config, agents, updates, wide)
    for _ in range(repeats):
        for case in cases:
            case.times.append(_time(case.run))
    rows = [summarise(case, peak) for case in cases]
    ratio = rows[1]["median_s"] / rows[0]["median_s"]
    return {"config": config.to_dict(), "agents": agents, "updates": updates, "repeats": repeats,
            "jax": jax.__version__, "devices": [str(d) for d in jax.devices()],
            "matmul_flops_per_s_by_size": peaks, "matmul_peak_flops_per_s": peak, "cases": rows,
            "time_ratio": ratio, "speedup_over_sequential": agents / ratio,
            "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()), "cpus": os.cpu_count(),
            "load_average_1_5_15": {"before": load_before, "after": os.getloadavg()}}


def report(result: dict[str, Any]) -> None:
    peaks = result["matmul_flops_per_s_by_size"]
    sizes = ", ".join(f"{size}: {rate / 1e9:.0f}" for size, rate in peaks.items())
    print(f"float32 matmul GFLOP/s by size: {sizes}; peak {result['matmul_peak_flops_per_s'] / 1e9:.1f}; "
          f"{result['updates']} updates per call, median of {result['repeats']}")
    header = ("compile s", "median s", "steps/s", "GFLOP", "GFLOP/s", "% peak", "XLA GFLOP")
    print(f"{'':>10} " + " ".join(f"{h:>9}" for h in header))
    for row in result["cases"]:
        cells = (row["compile_s"], row["median_s"], row["env_steps_per_s"], row["matmul_flops"] / 1e9,
                 row["matmul_flops_per_s"] / 1e9, 100 * row["fraction_of_peak"],
                 row["xla_cost_analysis_flops"] / 1e9)
        print(f"{row['name']:>10} " + " ".join(f"{c:>9.2f}" for c in cells)
              + f"  ({row['median_s'] / result['cases'][0]['median_s']:.2f}x 1 seed)")
    print(f"{result['agents']} seeds take {result['time_ratio']:.2f}x one seed's time: "
          f"{result['speedup_over_sequential']:.2f}x the throughput of {result['agents']} sequential runs")
    load = result["load_average_1_5_15"]
    print(f"load average before {load['before'][0]:.2f}, after {load['after'][0]:.2f} (1 min)")


def main() -> None:
    parser = OneLineArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", type=Path, default=None, help="PPOConfig JSON (default: PPOConfig())")
    parser.add_argument("--agents", type=positive_int, default=16)
    parser.add_argument("--updates", type=positive_int, default=3, help="updates per timed call")
    parser.add_argument("--repeats", type=positive_int, default=3)
    parser.add_argument("--matmul-sizes", type=positive_int, nargs="+", default=[1024, 2048, 4096])
    parser.add_argument("--no-wide", action="store_true", help="skip the one agent with N x the envs")
    parser.add_argument("--out", type=Path, default=None, help="write the results as JSON here")
    args = parser.parse_args()
    try:
        config = PPOConfig() if args.config is None else PPOConfig.from_dict(
            json.loads(args.config.read_text()))
    except (OSError, ValueError) as err:  # unreadable file, bad JSON (a ValueError) or a bad config
        parser.error(f"config {args.config}: {err}")
    result = measure(config, args.agents, args.updates, args.repeats, args.matmul_sizes,
                     not args.no_wide)
    report(result)
    if args.out:
        atomic_write_json(args.out, result)


if __name__ == "__main__":
    main()
