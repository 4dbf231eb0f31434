"""The action and the value on a 2-D or 1-D slice of observation space.

The user picks two observation components (by name, e.g. "x" and "z", or index) and their ranges;
every other component is held at ``base`` (default zeros), e.g. d rho over the (x, z) plane at fixed y
and velocities. :func:`policy_profile` is the 1-D slice along one component (e.g. a foam policy's
(alpha_u, alpha_p) against its one-number state). All grid points go through the policy as one batch,
each as an episode start unless an (unbatched) recurrent ``state`` is given, which every point then
shares.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from jaxsimrl.introspect.figure import new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure


class PolicySlice(NamedTuple):
    x_name: str
    y_name: str
    x: np.ndarray  # (nx,) values of the x component
    y: np.ndarray  # (ny,) values of the y component
    actions: np.ndarray  # (ny, nx, A): row i is y[i], column j is x[j]
    values: np.ndarray  # (ny, nx) critic value (reward units)
    action_names: tuple[str, ...]


def policy_slice(policy: Any, x: str | int, y: str | int, x_range: tuple[float, float],
                 y_range: tuple[float, float], base: Any = None, resolution: int = 41,
                 state: Any = None) -> PolicySlice:
    """Deterministic actions and values of ``policy`` on a ``resolution`` x ``resolution`` grid."""
    ix, iy = _component(policy, x), _component(policy, y)
    if ix == iy:
        raise ValueError(f"x and y must be two different observation components, got {x!r} twice")
    if resolution < 2:
        raise ValueError(f"resolution must be at least 2, got {resolution}")
    xs, ys = np.linspace(*x_range, resolution), np.linspace(*y_range, resolution)
    grid = np.tile(_base(policy, base), (resolution * resolution, 1))
    grid_y, grid_x = np.meshgrid(ys, xs, indexing="ij")
    grid[:, ix], grid[:, iy] = grid_x.ravel(), grid_y.ravel()
    actions, values = _evaluate(policy, grid, state)
    shape = (resolution, resolution)
    return PolicySlice(policy.obs_names[ix], policy.obs_names[iy], xs, ys, actions.reshape(*shape, -1),
                       values.reshape(shape), tuple(policy.action_names))


class PolicyProfile(NamedTuple):
    x_name: str
    x: np.ndarray  # (n,) values of the component
    actions: np.ndarray  # (n, A)
    values: np.ndarray  # (n,) critic value (reward units)
    action_names: tuple[str, ...]


def policy_profile(policy: Any, x: str | int, x_range: tuple[float, float], base: Any = None,
                   resolution: int = 101, state: Any = None) -> PolicyProfile:
    """Deterministic actions and values of ``policy`` at ``resolution`` points of component ``x`` over
    ``x_range``, the other components at ``base`` (default zeros)."""
    ix = _component(policy, x)
    if resolution < 2:
        raise ValueError(f"resolution must be at least 2, got {resolution}")
    xs = np.linspace(*x_range, resolution)
    grid = np.tile(_base(policy, base), (resolution, 1))
    grid[:, ix] = xs
    actions, values = _evaluate(policy, grid, state)
    return PolicyProfile(policy.obs_names[ix], xs, actions.reshape(resolution, -1),
                         values.reshape(resolution), tuple(policy.action_names))


def plot_policy_profile(data: PolicyProfile, value: bool = True, points: Any = None) -> Figure:
    """One panel per action component (and the value) against the component; ``points`` = (x (N,),
    actions (N, A)) adds the observations and actions of real steps (e.g. a rollout's) as dots."""
    panels = len(data.action_names) + int(value)
    fig = new_figure(4.0 * panels, 3.4)
    axes = fig.subplots(1, panels, squeeze=False)[0]
    for i, (ax, name) in enumerate(zip(axes, data.action_names, strict=False)):
        ax.plot(data.x, data.actions[:, i], color="C0", label="policy (mean action)")
        if points is not None:
            ax.scatter(np.asarray(points[0]), np.asarray(points[1])[:, i], s=12, color="C3", zorder=3,
                       label="steps taken")
            ax.legend(fontsize=8)
        ax.set_ylabel(name)
    if value:
        axes[-1].plot(data.x, data.values, color="C2")
        axes[-1].set_ylabel("value")
    for ax in axes:
        ax.set_xlabel(data.x_name)
        ax.grid(alpha=0.3)
    return fig


def plot_policy_slice(data: PolicySlice, value: bool = True) -> Figure:
    """One heat map per action component (and the value), over the slice's plane."""
    panels = [(name, data.actions[..., i]) for i, name in enumerate(data.action_names)]
    if value:
        panels.append(("value", data.values))
    fig = new_figure(4.2 * len(panels), 3.6)
    extent = (data.x[0], data.x[-1], data.y[0], data.y[-1])
    for ax, (title, field) in zip(fig.subplots(1, len(panels), squeeze=False)[0], panels, strict=True):
        image = ax.imshow(field, origin="lower", extent=extent, aspect="auto", cmap="coolwarm")
        fig.colorbar(image, ax=ax)
        ax.set_title(title)
        ax.set_xlabel(data.x_name)
        ax.set_ylabel(data.y_name)
    return fig


def _base(policy: Any, base: Any) -> np.ndarray:
    base = np.zeros(policy.obs_dim, np.float32) if base is None else np.asarray(base, np.float32)
    if base.shape != (policy.obs_dim,):
        raise ValueError(f"base must have shape ({policy.obs_dim},), got {base.shape}")
    return base


def _evaluate(policy: Any, grid: np.ndarray, state: Any) -> tuple[np.ndarray, np.ndarray]:
    """Actions and values of every row of ``grid`` (one batch), from ``state`` shared by all rows."""
    batch_state = None if state is None else _broadcast(state, len(grid))
    actions, _ = policy.act(grid, batch_state)
    return np.asarray(actions), np.asarray(policy.value(grid, batch_state))


def _component(policy: Any, which: str | int) -> int:
    names = list(policy.obs_names)
    if isinstance(which, str):
        if which not in names:
            raise ValueError(f"unknown observation component {which!r} (known: {', '.join(names)})")
        return names.index(which)
    if not 0 <= which < len(names):
        raise ValueError(f"observation component {which} is out of range (0..{len(names) - 1})")
    return int(which)


def _broadcast(state: Any, size: int) -> Any:
    import jax

    return jax.tree.map(lambda leaf: np.broadcast_to(np.asarray(leaf), (size, *np.shape(leaf))), state)
