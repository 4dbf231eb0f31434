"""Paper figure "l3": the uncontrolled Lorenz system from (1, 12, 9) with rho = 28 (chaotic) and
rho = 20 (transiently chaotic: it settles on P- = (-7.12, -7.12, 19)), sigma = 10, beta = 8/3.

    python experiments/paper/fig_lorenz_trajectories.py

One 4000-step episode each (dt = 0.02, RK4, as the env steps). Writes fig_lorenz_trajectories.png and
fig_lorenz_trajectories.json (final states, distance to P-, share of steps with |velocity| > 40) beside
this script.
"""

from __future__ import annotations

from pathlib import Path

import jax
import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from jaxsimrl.envs.lorenz import P_MINUS, Lorenz, LorenzParams  # noqa: E402
from jaxsimrl.evaluation.lorenz_eval import Rollout, rollout, uncontrolled  # noqa: E402
from jaxsimrl.evaluation.plots import save_figure  # noqa: E402
from jaxsimrl.runs.atomic import atomic_write_json  # noqa: E402

HERE = Path(__file__).resolve().parent


def uncontrolled_run(params: LorenzParams) -> Rollout:
    """One uncontrolled episode from ``params.init_state``."""
    env, params = Lorenz(), params.replace(random_init=False)
    key = jax.random.PRNGKey(0)  # unused by the dynamics: deterministic from the fixed initial state
    start = jax.tree.map(lambda leaf: leaf[None], env.reset(key, params))
    return rollout(env, params, uncontrolled, (), start, key)


def main() -> None:
    fig = plt.figure(figsize=(12, 5.5))
    numbers = {}
    for panel, rho in enumerate((28.0, 20.0), start=1):
        params = LorenzParams(rho=rho)
        run = uncontrolled_run(params)
        xyz, speed = run.xyz[0], run.speed[0]
        ax = fig.add_subplot(1, 2, panel, projection="3d")
        ax.plot(*xyz.T, color="black", lw=0.5)
        ax.scatter(*xyz[0][:, None], color="green", s=30, label="start (1, 12, 9)")
        if rho == 20.0:
            ax.scatter(*np.asarray(P_MINUS)[:, None], color="red", marker="*", s=150, label="P-")
        ax.set(xlabel="x", ylabel="y", zlabel="z", title=f"rho = {rho:g}")
        ax.legend(loc="upper left", fontsize=8)
        numbers[f"rho={rho:g}"] = {
            "final_xyz": [round(float(v), 3) for v in xyz[-1]],
            "distance_to_P_minus_at_end": float(np.linalg.norm(xyz[-1] - np.asarray(P_MINUS))),
            "fraction_above_v_threshold": float(np.mean(speed > float(params.v_threshold))),
            "return": float(run.reward[0].sum())}
    fig.suptitle("Uncontrolled Lorenz system, sigma = 10, beta = 8/3, 4000 steps of dt = 0.02")
    fig.tight_layout()
    save_figure(fig, HERE / "fig_lorenz_trajectories.png")
    atomic_write_json(HERE / "fig_lorenz_trajectories.json", numbers)
    for name, values in numbers.items():
        print(name, values)


if __name__ == "__main__":
    main()
