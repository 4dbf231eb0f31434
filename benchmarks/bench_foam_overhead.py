"""Bridge overhead of the FIFO-paused persistent simpleFoam against the solver's own compute.

For each mesh, with SIMPLEC and constant factors (0.95, 0.95) at U = 44.2 m/s (the paper's training
criterion), it alternates ``--repeats`` times:

- ``env``: one FoamCaseEnv episode, a pause every ``--interval`` iterations;
- ``uninterrupted``: one simpleFoam run of the same episode case, start to end, with the same state
  function objects but no pause (foam_bridge._episode_case.make_uninterrupted);
- ``plain``: the same without any function object (the stock way to run the case).

Reported (medians over repeats, all runs of one repeat measured back to back): wall times, the
iterations (must agree), the solver's idle time per step (from its last output before a pause to the
release: everything the bridge does while the solver waits, an upper bound), the bridge process's CPU
time per step (parsing, polling, case I/O) and the overhead ratios. Timings on a loaded machine are
noisy; ratios within one repeat are what to compare.

    python benchmarks/bench_foam_overhead.py --mesh-scales 1.0 0.4 --repeats 3 --out /tmp/bench.json
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

from foam_bridge import _episode_case as episode_case
from foam_bridge import _template as template
from foam_bridge._config import FOLLOW_ALPHA_U, U_REF, FoamEnvConfig
from foam_bridge._env import FoamCaseEnv
from foam_bridge._logparse import LogParser
from foam_bridge._solver import run_to_end

ACTION = (0.95, 0.95)


def run_env_episode(env: FoamCaseEnv) -> dict[str, float]:
    """One episode with constant factors: wall time, iterations, steps, solver idle and bridge CPU."""
    env.reset(options={"inlet_velocity": U_REF})
    cpu, start = time.process_time(), time.perf_counter()
    while True:
        _, _, terminated, truncated, info = env.step(ACTION)
        if terminated or truncated:
            break
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    record = info["episode"]
    return {"wall_s": wall, "iterations": record["iterations"], "steps": record["steps"],
            "idle_s": record["solver_idle_s"], "bridge_cpu_s": cpu, "outcome": record["outcome"]}


def run_reference(env: FoamCaseEnv, directory: Path, keep_functions: bool) -> dict[str, float]:
    """simpleFoam start to end on a fresh copy of the episode case, no pause."""
    episode_case.write_episode_case(env.base, directory, env.cfg, U_REF, env.case_info)
    episode_case.make_uninterrupted(directory, env.cfg, *ACTION, functions=keep_functions)
    parser = LogParser(episode_case.CELLS_FUNCTION, episode_case.INLET_FUNCTION)
    code, wall = run_to_end(directory, env.openfoam, parser, timeout_s=1800)
    return {"wall_s": wall, "iterations": parser.converged_at or parser.completed, "exit_code": code}


def bench_mesh(mesh_scale: float, repeats: int, interval: int, work: Path,
               relax_k_omega: float | str = FOLLOW_ALPHA_U) -> dict:
    cfg = FoamEnvConfig(mesh_scale=mesh_scale, simple_variant="SIMPLEC", interval=interval,
                        max_iterations=4000, step_timeout_s=600.0, relax_k_omega=relax_k_omega,
                        work_dir=work / f"scale_{mesh_scale}")
    env = FoamCaseEnv(cfg)
    runs: dict[str, list[dict]] = {"env": [], "uninterrupted": [], "plain": []}
    try:
        cells = template.cell_count(env.base)
        for _ in range(repeats):
            runs["env"].append(run_env_episode(env))
            runs["uninterrupted"].append(run_reference(env, work / "reference", keep_functions=True))
            runs["plain"].append(run_reference(env, work / "plain", keep_functions=False))
    finally:
        env.close()
    return {"relax_k_omega": relax_k_omega, **summarise(mesh_scale, cells, runs)}


def summarise(mesh_scale: float, cells: int, runs: dict[str, list[dict]]) -> dict:
    med = {kind: {key: statistics.median(r[key] for r in rs) for key in ("wall_s", "iterations")}
           for kind, rs in runs.items()}
    env_runs = runs["env"]
    steps = env_runs[0]["steps"]
    solver_step_s = med["uninterrupted"]["wall_s"] / steps
    idle_step_s = statistics.median(r["idle_s"] for r in env_runs) / steps
    cpu_step_s = statistics.median(r["bridge_cpu_s"] for r in env_runs) / steps
    return {
        "mesh_scale": mesh_scale, "cells": cells, "steps": steps,
        "iterations": {kind: [r["iterations"] for r in rs] for kind, rs in runs.items()},
        "outcomes": [r["outcome"] for r in env_runs],
        "wall_s": {kind: [round(r["wall_s"], 3) for r in rs] for kind, rs in runs.items()},
        "median_wall_s": {kind: round(m["wall_s"], 3) for kind, m in med.items()},
        "env_over_uninterrupted": _ratios(env_runs, runs["uninterrupted"]),
        "env_over_plain": _ratios(env_runs, runs["plain"]),
        "solver_s_per_step": round(solver_step_s, 4),
        "solver_idle_ms_per_step": round(1e3 * idle_step_s, 3),
        "bridge_cpu_ms_per_step": round(1e3 * cpu_step_s, 3),
        "idle_overhead_pct": round(100 * idle_step_s / solver_step_s, 3),
        "cpu_overhead_pct": round(100 * cpu_step_s / solver_step_s, 3),
    }


def _ratios(numerators: list[dict], denominators: list[dict]) -> list[float]:
    """Wall-time ratios of runs measured in the same repeat (back to back)."""
    return [round(n["wall_s"] / d["wall_s"], 4) for n, d in zip(numerators, denominators, strict=True)]


def _k_omega(text: str) -> float | str:
    """A fixed k/omega factor, or "alpha_u" (FoamEnvConfig.relax_k_omega's FOLLOW_ALPHA_U)."""
    return text if text == FOLLOW_ALPHA_U else float(text)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mesh-scales", type=float, nargs="+", default=[1.0, 0.4])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--interval", type=int, default=100)
    parser.add_argument("--relax-k-omega", type=_k_omega, default=FOLLOW_ALPHA_U,
                        help="fixed k/omega relaxation (RESULTS_foam.md's second table and the grid study "
                        "use 0.8); default: alpha_u")
    parser.add_argument("--out", type=Path, default=None, help="write the results as JSON here")
    args = parser.parse_args()
    results = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "cpus": os.cpu_count(),
               "loadavg_start": os.getloadavg(), "runs": []}
    with tempfile.TemporaryDirectory(prefix="bench_foam_") as tmp:
        for scale in args.mesh_scales:
            run = bench_mesh(scale, args.repeats, args.interval, Path(tmp), args.relax_k_omega)
            results["runs"].append(run)
            print(json.dumps(run), flush=True)
    results["loadavg_end"] = os.getloadavg()
    if args.out is not None:
        args.out.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
