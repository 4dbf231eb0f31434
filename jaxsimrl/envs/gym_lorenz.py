"""A gymnasium front end to the pure-JAX Lorenz environment: one env, one jitted JAX step per call.

    import gymnasium, jaxsimrl
    env = gymnasium.make("jaxsimrl/Lorenz-v0", rho=20.0)
    obs, info = env.reset(seed=0, options={"state": [1.0, 12.0, 9.0]})
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

Keyword arguments of the constructor are :class:`LorenzParams` fields (``rho=``, ``obs_scale=``,
``random_init=``, ...). ``options={"state": [x, y, z]}`` starts that episode from the given point;
otherwise the start follows the params (uniform in ``[init_low, init_high]^3`` by default).
``info["state"]`` is the raw (x, y, z) after every reset and step, whatever ``obs_scale`` does to the
observation. The env ends its own episodes (``terminated`` after ``episode_steps``), so it is
registered without a TimeLimit. The JAX PRNG key is drawn from gymnasium's ``np_random``, so
``reset(seed=s)`` reproduces an episode exactly.
"""

from __future__ import annotations

import dataclasses
from collections import deque
from typing import Any

import gymnasium
import jax
import jax.numpy as jnp
import numpy as np
from gymnasium import spaces

from jaxsimrl.envs.lorenz import Lorenz, LorenzParams, LorenzState

_ARRAY_FIELDS = {"init_state": (3,), "obs_scale": (6,)}
_INT_FIELDS = ("terminal_window", "episode_steps", "max_steps")
_INT32_MAX = 2**31 - 1
_PARAM_FIELDS = tuple(f.name for f in dataclasses.fields(LorenzParams))
_OBS, _XYZ, _SCALARS = slice(0, 6), slice(6, 9), slice(9, 14)  # layout of _step_and_split's vector
_LORENZ = Lorenz()  # stateless: one instance lets every wrapper share the jit caches

# Rendering: an (x, z) projection, the classic "butterfly" view, of the recent trajectory.
_RENDER_SIZE = 256
_RENDER_X = (-40.0, 40.0)
_RENDER_Z = (-40.0, 70.0)
_RENDER_HISTORY = 2000


def make_params(**overrides: Any) -> LorenzParams:
    """LorenzParams from keyword overrides, checked: unknown names and bad shapes raise ValueError."""
    unknown = sorted(set(overrides) - set(_PARAM_FIELDS))
    if unknown:
        raise ValueError(f"unknown Lorenz parameter(s) {', '.join(unknown)}; "
                         f"valid: {', '.join(_PARAM_FIELDS)}")
    params = LorenzParams(**{name: _convert(name, value) for name, value in overrides.items()})
    if not params.init_low < params.init_high:
        raise ValueError(f"Lorenz parameters need init_low < init_high, got {params.init_low} and "
                         f"{params.init_high}")
    if params.action_fraction < 0:
        raise ValueError(f"Lorenz parameter action_fraction must be >= 0, got {params.action_fraction}")
    return params


def _convert(name: str, value: Any) -> Any:
    """One parameter value as the type LorenzParams expects (a ValueError names the field if not)."""
    if name in _ARRAY_FIELDS:
        return _as_vector(name, value, _ARRAY_FIELDS[name])
    if name == "random_init":
        if not isinstance(value, bool | np.bool_):
            raise ValueError(f"Lorenz parameter random_init must be True or False, got {value!r}")
        return bool(value)
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ValueError(f"Lorenz parameter {name} must be a number, got {value!r}")
    if not np.isfinite(value):
        raise ValueError(f"Lorenz parameter {name} must be finite, got {value!r}")
    if name in _INT_FIELDS:  # step counts are compared with the int32 LorenzState.t
        if int(value) != value or not 1 <= value <= _INT32_MAX:
            raise ValueError(f"Lorenz parameter {name} must be an integer in [1, 2**31 - 1], got {value!r}")
        return int(value)
    return float(value)


def _as_vector(name: str, value: Any, shape: tuple[int, ...]) -> jax.Array:
    try:
        array = np.asarray(value, dtype=np.float32)
    except (TypeError, ValueError):
        array = None
    if array is None or array.shape != shape or not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be {shape[0]} finite numbers, got {value!r}")
    return jnp.asarray(array)


class LorenzGymEnv(gymnasium.Env):
    """Single-environment gymnasium wrapper of :class:`jaxsimrl.envs.lorenz.Lorenz`.

    Spaces are float32 Boxes: the action space is the perturbation box (+-action_fraction x base
    (sigma, rho, beta)); the observation space is the unbounded 6-vector (x, y, z, dx/dt, dy/dt, dz/dt)
    times ``obs_scale``.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 50}

    def __init__(self, render_mode: str | None = None, **param_overrides: Any) -> None:
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        self.params = make_params(**param_overrides)
        # Device arrays once, instead of converting every Python float leaf at every call.
        self._device_params = jax.device_put(self.params)
        box = _LORENZ.action_space(self.params)
        self.action_space = spaces.Box(low=np.asarray(box.low, np.float32),
                                       high=np.asarray(box.high, np.float32), dtype=np.float32)
        self.observation_space = spaces.Box(low=-np.inf, high=np.inf, shape=(_LORENZ.obs_dim,),
                                            dtype=np.float32)
        self._state: LorenzState | None = None
        self._key: jax.Array | None = None
        self._trail: deque[np.ndarray] = deque(maxlen=_RENDER_HISTORY)

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        params = self._device_params
        unknown = sorted(set(options or {}) - {"state"})
        if unknown:
            raise ValueError(f"unknown reset option(s) {', '.join(map(str, unknown))}; only 'state' is known")
        if options and "state" in options:
            params = params.replace(random_init=False, init_state=_as_vector("options['state']",
                                                                           options["state"], (3,)))
        seed_words = self.np_random.integers(0, 2**32, size=2, dtype=np.uint32)
        obs, self._state, self._key = _reset_from_seed(jnp.asarray(seed_words), params)
        xyz = np.array(self._state.xyz, dtype=np.float32)
        self._trail = deque([xyz], maxlen=_RENDER_HISTORY)
        return np.array(obs, dtype=np.float32), {"state": xyz}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self._state is None:
            raise RuntimeError("LorenzGymEnv.step() called before reset()")
        action = np.asarray(action, dtype=np.float32)
        if action.shape != (3,):
            raise ValueError(f"action must have shape (3,), got {action.shape}")
        self._key, self._state, packed = _step_and_split(self._key, self._state, action, self._device_params)
        packed = np.asarray(packed)  # one device-to-host transfer per step
        obs, xyz = packed[_OBS].copy(), packed[_XYZ].copy()
        reward, terminated, truncated, speed, penalty = (float(v) for v in packed[_SCALARS])
        self._trail.append(xyz)
        info = {"state": xyz, "speed": speed, "terminal_penalty": penalty}
        return obs, reward, bool(terminated), bool(truncated), info

    def render(self) -> np.ndarray | None:
        """An RGB image of the recent trajectory in the (x, z) plane; the current point in red."""
        if self.render_mode != "rgb_array":
            return None
        image = np.zeros((_RENDER_SIZE, _RENDER_SIZE, 3), dtype=np.uint8)
        if not self._trail:
            return image
        rows, cols = _pixels(np.stack(self._trail))
        image[rows, cols] = 200
        r, c = rows[-1], cols[-1]
        image[max(r - 2, 0):r + 3, max(c - 2, 0):c + 3] = (255, 40, 40)
        return image


def _pixels(xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel (row, col) of each point's (x, z), clamped to the frame; z grows upwards."""
    last = _RENDER_SIZE - 1
    cols = (xyz[:, 0] - _RENDER_X[0]) / (_RENDER_X[1] - _RENDER_X[0]) * last
    rows = last - (xyz[:, 2] - _RENDER_Z[0]) / (_RENDER_Z[1] - _RENDER_Z[0]) * last
    return np.clip(rows, 0, last).astype(int), np.clip(cols, 0, last).astype(int)


@jax.jit
def _reset_from_seed(seed_words: jax.Array, params: LorenzParams):
    """Reset with a key built from two 32-bit words (64 bits of gymnasium's seed stream)."""
    key = jax.random.fold_in(jax.random.key(seed_words[0]), seed_words[1])
    reset_key, step_key = jax.random.split(key)
    obs, state = _LORENZ.reset(reset_key, params)
    return obs, state, step_key


@jax.jit
def _step_and_split(key: jax.Array, state: LorenzState, action: jax.Array, params: LorenzParams):
    """One env step; obs, raw state and scalars come back packed in one float32 vector (see _OBS...)."""
    key, step_key = jax.random.split(key)
    out = _LORENZ.step(step_key, state, action, params)
    scalars = jnp.stack([out.reward, out.terminated, out.truncated, out.info["speed"],
                         out.info["terminal_penalty"]]).astype(jnp.float32)
    return key, out.state, jnp.concatenate([out.obs, out.info["state"], scalars]).astype(jnp.float32)
