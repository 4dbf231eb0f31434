"""What the convergence check (FoamEnvConfig.confirm_alpha_u) costs an honest episode.

    python benchmarks/bench_confirm.py --mesh-scale 1.0 --repeats 3
    python benchmarks/bench_confirm.py --mesh-scale 0.4 --repeats 5

One episode of the constant (0.95, 0.875) under the test criterion at 50 m/s, with and without the
check at alpha_u 0.9, alternated ``--repeats`` times on one worker (so both see the same load). The
check passes at once for this run (tested), so the episodes are the same iterations and the difference
is the check: one SIMPLE iteration and a solver start-up in a scratch copy. Prints a markdown row
(medians) and the machine's load, for benchmarks/RESULTS_foam.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import statistics
import tempfile
import time

from foam_bridge._config import TEST_CONVERGENCE, FoamEnvConfig
from foam_bridge._env import FoamCaseEnv

FACTORS = (0.95, 0.875)


def episode(cfg: FoamEnvConfig) -> tuple[float, int, list[float]]:
    """(wall seconds from reset to the end, iterations, the checks' own wall seconds) of one episode."""
    with tempfile.TemporaryDirectory(prefix="bench_confirm_") as work, \
            FoamCaseEnv(dataclasses.replace(cfg, work_dir=work)) as env:
        started = time.perf_counter()
        env.reset(seed=0)
        while True:
            _, _, terminated, truncated, info = env.step(FACTORS)
            if terminated or truncated:
                break
        wall = time.perf_counter() - started
    record = info["episode"]
    return wall, int(record["iterations"]), [c["wall_time_s"] for c in record.get("confirmations", [])]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mesh-scale", type=float, default=1.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--confirm-alpha-u", type=float, default=0.9)
    args = parser.parse_args()
    plain = FoamEnvConfig(mesh_scale=args.mesh_scale, inlet_velocity=50.0, convergence=dict(TEST_CONVERGENCE))
    checked = dataclasses.replace(plain, confirm_alpha_u=args.confirm_alpha_u)
    walls: dict[str, list[float]] = {"plain": [], "checked": []}
    checks: list[float] = []
    iterations = set()
    for _ in range(args.repeats):
        for name, cfg in (("plain", plain), ("checked", checked)):
            wall, its, own = episode(cfg)
            walls[name].append(wall)
            iterations.add(its)
            checks += own
    base, with_check = statistics.median(walls["plain"]), statistics.median(walls["checked"])
    print(f"machine: {platform.machine()} {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.2f}; "
          f"iterations per episode: {sorted(iterations)}")
    print("episodes (s): " + "; ".join(f"{name} {', '.join(f'{w:.2f}' for w in values)}"
                                        for name, values in walls.items()))
    print("| mesh | repeats | episode without / with the check (median s) | ratio | one check (median s) |")
    print("|---|---|---|---|---|")
    print(f"| {args.mesh_scale:g} | {args.repeats} | {base:.2f} / {with_check:.2f} | "
          f"{with_check / base:.3f} | {statistics.median(checks):.3f} |")


if __name__ == "__main__":
    main()
