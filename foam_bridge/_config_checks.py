"""What a FoamEnvConfig may hold: the choices of its enumerated fields (the SIMPLE variants, the action's
entries, the turbulence factor's two modes, the rewards, the pivots) and the checks of every field.

Internal to foam_bridge (its users import the choices from ``foam_bridge``, or from foam_bridge._config,
which re-exports them; FoamEnvConfig.validate runs the checks); names here may change. A bad field is a
one-line ``ValueError`` naming it: ``FoamEnvConfig.<field>: expected ..., got ...``.
"""

from __future__ import annotations

import math
from typing import Any

SIMPLE_VARIANTS = ("SIMPLE", "SIMPLEC")
#: The action's entries, in order (the third only with relax_k_omega="action").
ACTION_NAMES = ("alpha_u", "alpha_p", "alpha_t")
#: ``relax_k_omega`` value that relaxes the turbulence fields with alpha_u (the agent's momentum factor).
FOLLOW_ALPHA_U = "alpha_u"
#: ``relax_k_omega`` value that makes the turbulence fields' factor a third action, alpha_t.
K_OMEGA_ACTION = "action"
#: The costs a reward can count (FoamEnvConfig.reward): SIMPLE iterations (the paper's), the linear
#: solvers' inner iterations (every "No Iterations" of the log) or the solver's own CPU seconds.
REWARDS = ("iterations", "linear-iterations", "solver-time")
#: What a controller's share 0.5 stands for on a case (FoamEnvConfig.pivot_at).
PIVOTS = ("family", "own")


def check_fields(cfg: Any) -> None:
    """Check every field of ``cfg``, a FoamEnvConfig; raise a one-line ``ValueError`` naming the first bad
    one. (Typed Any: this module is below foam_bridge._config, which imports it.)"""
    _check(cfg.mesh_scale > 0 and math.isfinite(cfg.mesh_scale), "mesh_scale", cfg.mesh_scale)
    _check_height(cfg.step_height)
    if cfg.velocity_range is not None:
        low, high = cfg.velocity_range
        _check(0 < low <= high and math.isfinite(high), "inlet_velocity", cfg.inlet_velocity)
    if cfg.inlet_turbulence is not None:
        values = tuple(cfg.inlet_turbulence)
        _check(len(values) == 2 and all(v > 0 and math.isfinite(v) for v in values), "inlet_turbulence",
               cfg.inlet_turbulence, "(intensity > 0, nu_t/nu > 0)")
    for name in ("inlet_patch", "velocity_field", "pressure_field"):
        value = getattr(cfg, name)
        none_ok = name == "inlet_patch" and value is None  # a case without an inlet
        _check(isinstance(value, str) and value != "" or none_ok, name, value,
               "a non-empty name" + " (or None: the case has no inlet)" * (name == "inlet_patch"))
    _check(cfg.inlet_patch is not None or not (cfg.builtin or cfg.velocity_range is not None),
           "inlet_patch", None, "an inlet patch where the inlet speed is set (the built-in case sets it)")
    _check(cfg.simple_variant is None or cfg.simple_variant in SIMPLE_VARIANTS, "simple_variant",
           cfg.simple_variant, f"None or one of {SIMPLE_VARIANTS}")
    _check(_is_int(cfg.ranks) and cfg.ranks >= 1 and (cfg.ranks == 1 or not cfg.builtin), "ranks",
           cfg.ranks, "an integer >= 1 (> 1 only for a user's case_dir)")
    _check(_is_int(cfg.interval) and cfg.interval >= 1, "interval", cfg.interval, "an integer >= 1")
    _check(cfg.settle is None or 0 < cfg.settle < 1, "settle", cfg.settle, "None or a tolerance in (0, 1)")
    _check(_is_int(cfg.state_interval) and cfg.state_interval >= 1
           and cfg.interval % cfg.state_interval == 0, "state_interval", cfg.state_interval,
           f"an integer >= 1 that divides interval ({cfg.interval})")
    _check(_is_int(cfg.max_iterations) and cfg.max_iterations >= cfg.interval, "max_iterations",
           cfg.max_iterations, "an integer >= interval")
    size = cfg.action_size
    _check(len(cfg.action_low) == size and len(cfg.action_high) == size, "action_low/action_high",
           (cfg.action_low, cfg.action_high),
           f"{size} values each ({', '.join(ACTION_NAMES[:size])})")
    for lo, hi in zip(cfg.action_low, cfg.action_high, strict=True):
        _check(0 < lo <= hi <= 1, "action_low/action_high", (cfg.action_low, cfg.action_high),
               "0 < low <= high <= 1")
    if cfg.relax_k_omega not in (None, FOLLOW_ALPHA_U, K_OMEGA_ACTION):
        factor = cfg.relax_k_omega
        _check(isinstance(factor, int | float) and not isinstance(factor, str) and 0 < factor <= 1,
               "relax_k_omega", factor,
               f"None, {FOLLOW_ALPHA_U!r}, {K_OMEGA_ACTION!r} or a factor in (0, 1]")
    _check(len(cfg.convergence) > 0 and all(v > 0 for v in cfg.convergence.values()), "convergence",
           dict(cfg.convergence), "a non-empty {field: threshold > 0}")
    if cfg.confirm_alpha_u is not None:
        factor = cfg.confirm_alpha_u
        _check(isinstance(factor, int | float) and not isinstance(factor, bool) and 0 < factor < 1,
               "confirm_alpha_u", factor, "None or a factor in (0, 1)")
    if cfg.confirm_alpha_t is not None:
        factor = cfg.confirm_alpha_t
        _check(isinstance(factor, int | float) and not isinstance(factor, bool) and 0 < factor <= 1
               and cfg.confirm_alpha_u is not None, "confirm_alpha_t", factor,
               "None, or a factor in (0, 1] beside a confirm_alpha_u")
    _check(_is_int(cfg.residual_features) and cfg.residual_features >= 0, "residual_features",
           cfg.residual_features, "an integer >= 0")
    if cfg.observed_fields is not None:
        names = cfg.observed_fields
        _check(isinstance(names, tuple) and len(names) > 0 and len(set(names)) == len(names)
               and all(isinstance(name, str) and name != "" for name in names), "observed_fields",
               names, "None or a non-empty tuple of distinct field names")
    _check(cfg.reward in REWARDS, "reward", cfg.reward, f"one of {REWARDS}")
    _check(cfg.reward_scale > 0 and math.isfinite(cfg.reward_scale), "reward_scale", cfg.reward_scale)
    _check(cfg.freeze_decades is None or not isinstance(cfg.freeze_decades, bool) and isinstance(
        cfg.freeze_decades, int | float) and 0 <= cfg.freeze_decades < math.inf, "freeze_decades",
        cfg.freeze_decades, "None or a number of decades >= 0")
    pivot = cfg.action_pivot
    _check(pivot is None or len(pivot) == len(cfg.action_low) and all(
        lo <= x <= hi for x, lo, hi in zip(pivot, cfg.action_low, cfg.action_high, strict=True)),
        "action_pivot", pivot, "None or one factor per action, each in the box")
    radius = cfg.action_radius
    _check(radius is None or not isinstance(radius, bool) and isinstance(radius, int | float)
           and 0 < radius <= 1, "action_radius", radius, "None or a factor step in (0, 1]")
    _check(cfg.pivot_at in PIVOTS, "pivot_at", cfg.pivot_at, f"one of {', '.join(PIVOTS)}")
    _check(not cfg.observe_algorithm or cfg.variant is not None, "observe_algorithm",
           cfg.observe_algorithm, "simple_variant set (the algorithm observed)")
    _check(_is_int(cfg.start_time) and cfg.start_time >= 0 and not (cfg.start_time and cfg.builtin),
           "start_time", cfg.start_time, "an integer >= 0 (0 for the built-in case)")
    for name in ("observe_progress", "observe_action", "observe_gain", "scale_free_state"):
        _check(isinstance(getattr(cfg, name), bool), name, getattr(cfg, name), "true or false")
    _check(cfg.state_scale > 0, "state_scale", cfg.state_scale)
    _check(cfg.step_timeout_s > 0, "step_timeout_s", cfg.step_timeout_s)
    _check(cfg.divergence_threshold > 0, "divergence_threshold", cfg.divergence_threshold)
    _check(cfg.state_divergence_ratio > 0 and math.isfinite(cfg.state_divergence_ratio),
           "state_divergence_ratio", cfg.state_divergence_ratio)
    if cfg.failure_penalty is not None:
        _check(math.isfinite(cfg.failure_penalty), "failure_penalty", cfg.failure_penalty, "finite")


def _check_height(height: object) -> None:
    """A step height > 0, or a range (low, high) with 0 < low <= high."""
    if isinstance(height, tuple | list):
        ok = len(height) == 2 and all(_is_number(h) and h > 0 and math.isfinite(h) for h in height) \
            and height[0] <= height[1]
        _check(ok, "step_height", height, "a height > 0 or a range (low, high) with 0 < low <= high")
        return
    _check(_is_number(height) and height > 0 and math.isfinite(height), "step_height", height)  # type: ignore[operator]


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _is_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _check(ok: bool, name: str, value: object, expected: str = "a finite number > 0") -> None:
    if not ok:
        raise ValueError(f"FoamEnvConfig.{name}: expected {expected}, got {value!r}")
