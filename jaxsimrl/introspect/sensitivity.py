"""Sensitivity of the action to each observation component along a trajectory.

At every step t of a recorded rollout, ``jax.jacobian`` of the deterministic action (env units) with
respect to the raw observation, taken from the recurrent state the policy had just before t (so the
normalisation and the LSTM's memory are part of it): J[t, a, o] = d action_a / d obs_o. All steps
are done at once with ``vmap``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxsimrl.introspect.figure import new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure


class Sensitivity(NamedTuple):
    step: np.ndarray  # (T,)
    jacobian: np.ndarray  # (T, A, O)
    obs_names: tuple[str, ...]
    action_names: tuple[str, ...]


def action_sensitivity(policy: Any, record: dict[str, np.ndarray], episode: int = 0) -> Sensitivity:
    """d action / d obs at every step of episode ``episode`` of ``record`` (from ``policy.rollout``)."""
    obs = jnp.asarray(record["obs"][episode])
    steps = obs.shape[0]
    carry = _carries_before(policy, record, episode, steps)
    starts = jnp.arange(steps) == 0
    jacobian = jax.jit(jax.vmap(jax.jacobian(policy.mean_action)))(obs, carry, starts)
    return Sensitivity(np.arange(steps), np.asarray(jacobian), tuple(policy.obs_names),
                       tuple(policy.action_names))


def plot_sensitivity(data: Sensitivity, dt: float = 1.0, time_label: str = "step") -> Figure:
    """One heat map per action component: observation components (rows) over time (columns)."""
    actions = len(data.action_names)
    fig = new_figure(11, 2.4 * actions)
    time = data.step * dt
    for a, ax in enumerate(fig.subplots(actions, 1, sharex=True, squeeze=False)[:, 0]):
        field = data.jacobian[:, a, :].T
        limit = float(np.max(np.abs(field))) or 1.0
        extent = (time[0], time[-1], len(data.obs_names) - 0.5, -0.5)
        image = ax.imshow(field, aspect="auto", cmap="RdBu_r", vmin=-limit, vmax=limit,
                          interpolation="nearest", extent=extent)
        ax.set_yticks(range(len(data.obs_names)), data.obs_names)
        ax.set_ylabel(f"∂({data.action_names[a]}) / ∂")
        fig.colorbar(image, ax=ax)
    ax.set_xlabel(time_label)
    return fig


def _carries_before(policy: Any, record: dict[str, np.ndarray], episode: int, steps: int) -> Any:
    """The carry each step started from: zeros at t = 0, then the carry the previous step left."""
    if "hidden" not in record:  # a feed-forward network: its dummy carry plays no part
        return jax.tree.map(lambda leaf: jnp.broadcast_to(leaf, (steps, *leaf.shape)), policy.initial_state())

    def shifted(after: np.ndarray) -> jax.Array:
        after = jnp.asarray(after[episode])
        return jnp.concatenate([jnp.zeros_like(after[:1]), after[:-1]])

    return shifted(record["cell"]), shifted(record["hidden"])
