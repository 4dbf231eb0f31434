"""FoamEnvConfig: every constant of one simpleFoam solver-control environment.

The environment (Pawar & Maulik, "Solver convergence acceleration"): a steady simpleFoam run of a 2D
turbulent backward-facing step (k-omega SST). Every ``interval`` SIMPLE iterations the agent sets the
under-relaxation factors (alpha_u, alpha_p); the reward is -(K_t - K_{t-1}), K = SIMPLE iterations run,
so an episode's return is minus its total iterations (or minus another cost of the run: ``reward``).

The config is a frozen dataclass: it is hashable by identity of its values, picklable (it travels to
worker processes) and validated by :meth:`FoamEnvConfig.validate`, which raises a one-line
``ValueError`` naming the bad field. Constructing a config does not validate it (so that
``dataclasses.replace`` chains stay cheap); :class:`foam_bridge._env.FoamCaseEnv` validates on
construction. :meth:`FoamEnvConfig.to_json` / :meth:`FoamEnvConfig.from_json` are its one JSON codec (the
"foam" section of a train-foam run's config.json).

The dataclass, its derived properties and the helpers that derive from a config are here; beside them,
foam_bridge._constants holds the numbers its fields take, foam_bridge._config_checks the choices and
validate's checks (both re-exported here), foam_bridge._config_json the JSON codec and
foam_bridge._work_dirs the work directory.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from foam_bridge._config_checks import (
    ACTION_NAMES,
    FOLLOW_ALPHA_U,
    K_OMEGA_ACTION,
    PIVOTS,
    REWARDS,
    SIMPLE_VARIANTS,
    check_fields,
)
from foam_bridge._config_json import config_to_json, config_values
from foam_bridge._constants import (
    BUILTIN_ACTION_BOUNDS,
    BUILTIN_INLET_VELOCITY,
    BUILTIN_RELAX_K_OMEGA,
    BUILTIN_SIMPLE_VARIANT,
    MESH_SCALE_USABLE_MIN,
    NEVER_CONVERGED,
    OBSERVATION_BOUND,
    PAPER_INLET_TURBULENCE,
    STEP_HEIGHT_H,
    TEST_CONVERGENCE,
    TRAIN_CONVERGENCE,
    U_REF,
)

#: The constants and choices are re-exported: code imports them from here, beside the config.
__all__ = [
    "U_REF", "STEP_HEIGHT_H", "TRAIN_CONVERGENCE", "TEST_CONVERGENCE", "NEVER_CONVERGED", "SIMPLE_VARIANTS",
    "ACTION_NAMES", "FOLLOW_ALPHA_U", "K_OMEGA_ACTION", "BUILTIN_ACTION_BOUNDS", "BUILTIN_SIMPLE_VARIANT",
    "BUILTIN_RELAX_K_OMEGA", "BUILTIN_INLET_VELOCITY", "PAPER_INLET_TURBULENCE", "MESH_SCALE_USABLE_MIN",
    "REWARDS", "PIVOTS", "OBSERVATION_BOUND", "FoamEnvConfig", "absolute_path", "cost_per_iteration",
    "failure_reward", "without_convergence_test",
]


@dataclass(frozen=True)
class FoamEnvConfig:
    """Configuration of one simpleFoam solver-control environment.

    Case:
        case_dir: ``None`` -> the built-in backward-facing step template (foam_bridge/cases/
            backward_facing_step, derived from OpenFOAM's backwardFacingStep2D tutorial); otherwise the
            path of a user's simpleFoam case (``system/``, ``constant/`` with a mesh or a
            ``system/blockMeshDict``, and ``0/``). The user's case is copied, never modified.
        mesh_scale: resolution factor of the built-in case: every block's cell count is multiplied by it
            and rounded (at least 1 cell per direction). 1.0 = the tutorial's 20,540 cells; 0.4 gives
            3,276 cells, 0.5 gives 5,024. Use >= MESH_SCALE_USABLE_MIN (0.4; the tests use 0.4): measured
            at 50 m/s, 0.25 (1,264 cells) and 0.3 (1,866) diverge or oscillate to the cap with the
            high factors that are best on the full mesh ((0.95, 0.95) SIMPLEC; plain SIMPLE diverges
            with alpha_u >= 0.7 up to 0.35), and converge only with some low ones, so they are a
            different control problem; 0.35 is borderline. Ignored for a user's case.
        step_height: step height in metres of the built-in case. 0.0127 (h) is the paper's training
            geometry, 0.0254 (2h) its second test geometry: only the step is deepened (the downstream
            floor moves down), the inlet channel and the domain length stay the same. A ``(low, high)``
            range: a family of geometries, the height drawn uniformly per episode from the seeded
            episode RNG *after* the inlet velocity (so a fixed height draws exactly the velocities it
            always drew); ``reset(options={"step_height": x})`` fixes it for one episode. Each height's
            mesh is built by blockMesh when first met and a few are kept (foam_bridge._env).
        inlet_velocity: inlet speed in m/s: a ``(low, high)`` range sampled uniformly per episode from
            the seeded episode RNG, or a fixed float. ``reset(options={"inlet_velocity": v})``
            overrides it for one episode. ``None`` (default): the built-in case samples
            BUILTIN_INLET_VELOCITY (35-65 m/s); a user's case keeps its own inlet (changing it is
            opt-in; it needs a ``fixedValue`` inlet, whose direction is kept).
        inlet_turbulence: ``(intensity I, nu_t/nu)``: when the inlet speed is set, the inlet k and omega
            (fixedValue entries) become ``k = 1.5 (I U)^2`` and ``omega = k / (nu_t/nu * nu)``, with
            ``nu`` read from the case's constant/transportProperties. ``None`` (default): the built-in
            case uses PAPER_INLET_TURBULENCE (and also sets the internal k and omega); a user's case
            keeps its own turbulence boundary conditions.
        inlet_patch: name of the inlet patch (its U is set and its mean |U|^2 is observed); None for a
            case without an inlet (a cavity, a closed mixer): the state is the cells' mean |U|^2 alone and
            the inlet speed cannot be set.
        velocity_field, pressure_field: names of the fields relaxed by alpha_u and alpha_p.
        turbulence_fields: fields relaxed by ``relax_k_omega``, and set by ``inlet_turbulence``.
        simple_variant: "SIMPLE" (``consistent no``) or "SIMPLEC" (``consistent yes``). ``None``
            (default): SIMPLEC for the built-in case, the case's own choice for a user's case.
        start_time: the time directory of a user's case its episodes start from (0: ``0/``; a later
            one: a partly converged run goes on from its fields, as ``startFrom latestTime`` would).
            Iterations K are counted from it (the solver's time is start_time + K; the pauses, the
            budget, the writes and the confirmation's time directories follow), and the base case
            keeps that directory, without its ``uniform/time`` (its time index then counts from 0 at
            start_time, so that the writes every ``max_iterations`` or ``interval`` iterations of K
            fall where they do from 0). An integer: the bridge runs deltaT 1.
        ranks: MPI ranks of the episode's solver (1: plain simpleFoam; N > 1: the episode case is
            decomposed into N subdomains and runs ``mpirun -np N simpleFoam -parallel``, see
            foam_bridge._parallel). A user's case only.

    MDP:
        interval: SIMPLE iterations per env step (the paper: 100).
        max_iterations: iteration cap; reaching it ends the episode (outcome ``truncated``, terminated).
        action_low, action_high: box of the action (:attr:`action_size` entries: alpha_u, alpha_p and,
            with ``relax_k_omega="action"``, alpha_t); actions are clipped into it. Default: the
            built-in case's [0.2, 0.95]^2, which becomes [0.2, 0.95]^3 with the third action (any other
            box must have action_size entries); for a user's case foam_bridge._user_case.case_defaults
            gives a box its algorithm tolerates (train-foam applies it to ``--case``).
        relax_k_omega: relaxation factor of the turbulence fields: a float (fixed), FOLLOW_ALPHA_U
            (``"alpha_u"``: the agent's momentum factor) or K_OMEGA_ACTION (``"action"``: a third
            action alpha_t relaxes them; on a user's case "them" are the fields its dry run solved
            besides the velocity and pressure, e.g. k and epsilon). ``None`` (default): 0.8 for the
            built-in case, the case's own factors for a user's case. Every other field keeps the
            case's own factor.
        convergence: field -> threshold on the solver's initial residual (vector fields: the largest
            component), as simpleFoam's own ``SIMPLE.residualControl``. Default: the paper's training
            criterion (TRAIN_CONVERGENCE); TEST_CONVERGENCE is its test criterion. A user's case's own
            residualControl: foam_bridge._user_case.case_defaults (train-foam applies it to ``--case``).
        confirm_alpha_u: a convergence test that relaxation cannot move. simpleFoam normalises each
            initial residual with the relaxed matrix, whose diagonal grows as 1/alpha_u, so lowering
            alpha_u lowers the residuals the criterion reads at once, field unchanged (on 2h at 50 m/s,
            alpha_u 0.2 met the test criterion at a U field 21 % from the solution,
            experiments/foam/README.md). ``None`` (default, the paper's): converged when the solver's
            own test is met. A factor in (0, 1), e.g. 0.9 (the tutorial's alpha_u): the criterion must
            also hold for the residuals normalised at that relaxation. When the solver meets it at K,
            the bridge runs one SIMPLE iteration from the fields of K in a scratch copy, with this
            alpha_u (the step's alpha_p, the case's k/omega factor), and reads its initial residuals
            (foam_bridge._confirm). If they meet the criterion the episode is converged at K. If not,
            the solver restarts from the fields of K with the step's factors and without its own
            test, and the check runs at every later step boundary whose residuals meet the criterion;
            the first one that passes ends the episode (converged at that boundary). Every check is
            in the episode record's "confirmations".
        confirm_alpha_t: the check's factor for the turbulence fields when alpha_t is an action
            (``relax_k_omega`` "action"); ``None`` (default): ``confirm_alpha_u``. solve
            sets the case's own turbulence factor, so that k/epsilon/omega are held to the normalisation
            the user's own run reads, as U is: checked at the own alpha_u, a SIMPLEC case whose own
            turbulence factor is below its alpha_u (0.77 and 0.89) failed the check at its own factors,
            and its run went on to the next step boundary (1.10-1.21x own iterations on 4 of 12
            generated cases;
            experiments/controller/generated-v1-setup/control-overhead-alpha-u-check.jsonl).
        residual_features: extra observation entries: log10 of the latest initial residual of each
            observed field (:attr:`observed`) at each of the last N step boundaries (0 = the paper's 1-D
            state; before the first boundaries: 0). Their trends are the differences of these levels,
            which the policy's first (linear) layer forms exactly, so they are not observed separately.
        observed_fields: the fields whose residuals the residual features hold, in order. ``None``
            (default): the ``convergence`` fields in its order (every run before this field). Set apart
            from the criterion so that a controller run on a user's case (jaxsimrl solve) sees the
            fields it was trained on, in its order, while the case keeps its own criterion; a field
            the solver does not solve reads as a residual of 1 (log 0).
        observe_progress: one more observation entry, K / max_iterations (0 at reset, 1 at the cap).
        observe_action: action_size more entries, the factors in force (the last action after
            clipping; at reset, before any action: the box centre (action_low + action_high) / 2).
        observe_gain: one more entry, after the factors: the last step's gain, the decades by which the
            criterion distance (the worst criterion field's log10(residual / threshold)) fell over it
            (negative where it rose; 0 at reset and after the first step; clipped to +-5). With the
            factors in force it says what the last choice earned on this case, so a recurrent policy
            can probe and settle within one run (issue 47); residual features hold levels, not the
            criterion's distance, which differs by case.
        scale_free_state: the state is divided by the episode's own inlet mean |U|^2 (at reset)
            instead of ``state_scale``: 1 + mean_cells |U|^2 / mean_inlet |U|^2, the same at 10 and
            50 m/s for similar flows (a user's case whose inlet has no value: ``state_scale``).
            Observation layout: state, residual features, progress, algorithm, action, gain.
        state_scale: the observed state is (mean_inlet |U|^2 + mean_cells |U|^2) / state_scale
            (default U_REF**2 = 44.2**2, so the state is O(1)).
        observe_state: False leaves the flow state out of the observation (a controller for many
            geometries, or a case without an inlet: the state's scale is one flow's).
        observe_algorithm: one more observation entry after the progress: 1 for SIMPLEC, 0 for plain
            SIMPLE (``simple_variant`` must then be set), so one controller can act on both.
        action_share: the action is a share of the box, a in [0, 1] per factor, and the factors are
            action_low + a (action_high - action_low) (:func:`factors_of`): one controller acts in each
            case's own box (plain SIMPLE's is the case's own factors' neighbourhood,
            foam_bridge._user_case), where absolute factors would mean a different thing in each.
        action_pivot: with ``action_share``, the factors at share 0.5 (the case's own, so that one
            controller's "0.5" is every case's own settings, above it more aggressive, below more
            cautious); the map is linear from action_low to it and from it to action_high. None: linear
            over the whole box.
        action_radius: with ``action_share``, the factors at share a are pivot + (2a - 1) x
            action_radius, clipped into the box (the pivot: ``action_pivot``, else the box's centre):
            one share moves every factor alike both ways. The piecewise map above moves alpha_u below a
            pivot of 0.7 in a box from 0.2 twice as far as above it, so a policy's symmetric exploration
            around share 0.5 drifts cautious (issue 47: experiments/controller/generated-v1-setup/
            exploration.py). None: that piecewise map.
        pivot_at: what a controller's share 0.5 stands for on a case of its own (the application's rule
            that sets ``action_pivot`` for each case, recorded with the policy so that training and use
            agree): "family" (default), the training family's constant for the case's algorithm; "own",
            the case's own factors, so that the initial policy is the user's own run (issue 47). The
            env itself reads only ``action_pivot``.
        reward_scale: every step's reward (a failure's too) is multiplied by it; a family of cases that
            differ tenfold in iterations weighs each alike with 100 / the case's own iterations.
        freeze_decades: once the run is within this many decades of its criterion (the worst
            criterion field's log10(residual / threshold) at a step's end), every later step keeps the
            factors in force whatever the action (None: never). A change of alpha_u there changes the
            discrete problem the solver iterates on and the run re-converges: airFoil2D's own factors
            jittered by +-0.03 share every 50 iterations took 569 iterations against 292
            (experiments/controller/family-v3-setup/jitter.json); jaxsimrl.apps.foam.solve.rules freezes at 1.
        settle: the answer monitor's tolerance (foam_bridge._answer_monitor, as ``jaxsimrl solve
            --settle``): an episode whose answer has settled within it, or oscillates about a steady mean,
            ends at that step with outcome "settled" or "oscillating" (terminated, not a failure). None
            (default): episodes end as before, so recorded runs replay.
        reward: the cost whose increase is the negative reward of a step, one of REWARDS:
            "iterations" (default, the paper's: SIMPLE iterations K), "linear-iterations" (the inner
            iterations of every linear solve, all fields: what one SIMPLE iteration costs changes with
            the factors, e.g. 10.8-11.3 near (0.95, 0.9) and 8.6-10.2 with random factors on the full
            mesh) or "solver-time" (the
            solver's ExecutionTime, CPU seconds: it does not count the pauses between steps nor a
            busy pool's waiting, but it varies from run to run, so a run with it is not bit-
            reproducible). Every episode record holds all three costs whatever the reward.
        failure_penalty: reward of the step on which the solver failed (crashed, diverged, hung);
            ``None`` -> as if it had run to max_iterations: -(max_iterations - K_{t-1}) SIMPLE
            iterations, each at the episode's mean cost per iteration so far for the other rewards,
            so that the episode's return is about minus the cost of a run to the cap. A penalty above
            that (nearer 0) makes failing pay better than running on to the cap.
        divergence_threshold: an initial residual above this (or NaN/Inf) ends the episode as
            ``diverged``.
        state_divergence_ratio: a state term (mean |U|^2 over the cells or over the inlet) above this
            multiple of the inlet's |U|^2 (or NaN/Inf) ends the episode as ``diverged``. Healthy runs
            measured at mesh_scale 0.25-0.4 peaked at 13 x (typically 1-6 x), diverging ones reached
            1e26 x within ~50 iterations; the default 1e3 catches a blow-up long before the observation
            leaves float32's range. (The observation is also clipped to +-OBSERVATION_BOUND.)
        state_interval: the state's function objects (mean |U|^2 over the cells and the inlet) run every
            this many iterations of OpenFOAM's time index (a divisor of ``interval``; a run started from
            a later time counts from that time's index, so a step boundary may go without its state): 1
            (default) every iteration. They cost 3-5 % of a small case's solver CPU
            (experiments/controller/generated-v1-setup/function-objects.jsonl); solve runs them every 5
            for a controller that does not observe the state, whose only use of it is the divergence
            check above (a blow-up takes ~50 iterations to leave float32's range).

    Host:
        step_timeout_s: watchdog: wall-clock seconds one step may take before the solver counts as hung.
        work_dir: parent directory of the per-env case directories (``None`` -> a fresh temporary
            directory); nothing is written to the current directory.
        keep_cases: keep the case directories after close() (for debugging).
        openfoam_path: ``PATH`` used to locate simpleFoam/blockMesh (``None`` -> the caller's PATH).
            The solver itself runs with a clean environment built from it.
    """

    case_dir: Path | str | None = None
    mesh_scale: float = 1.0
    step_height: float | tuple[float, float] = STEP_HEIGHT_H
    inlet_velocity: tuple[float, float] | float | None = None
    inlet_patch: str | None = "inlet"
    velocity_field: str = "U"
    pressure_field: str = "p"
    turbulence_fields: tuple[str, ...] = ("k", "omega")
    simple_variant: str | None = None
    interval: int = 100
    max_iterations: int = 4000
    action_low: tuple[float, float] = (0.2, 0.2)
    action_high: tuple[float, float] = (0.95, 0.95)
    relax_k_omega: float | str | None = None
    convergence: Mapping[str, float] = field(default_factory=lambda: dict(TRAIN_CONVERGENCE))
    confirm_alpha_u: float | None = None
    confirm_alpha_t: float | None = None
    residual_features: int = 0
    reward: str = "iterations"
    observe_state: bool = True
    observe_algorithm: bool = False
    action_share: bool = False
    action_pivot: tuple[float, ...] | None = None
    action_radius: float | None = None
    pivot_at: str = "family"
    reward_scale: float = 1.0
    freeze_decades: float | None = None
    settle: float | None = None
    state_scale: float = U_REF**2
    failure_penalty: float | None = None
    divergence_threshold: float = 1e3
    state_divergence_ratio: float = 1e3
    state_interval: int = 1
    step_timeout_s: float = 120.0
    work_dir: Path | str | None = None
    keep_cases: bool = False
    openfoam_path: str | None = None
    inlet_turbulence: tuple[float, float] | None = None
    observe_progress: bool = False
    observe_action: bool = False
    observe_gain: bool = False
    scale_free_state: bool = False
    observed_fields: tuple[str, ...] | None = None
    start_time: int = 0
    ranks: int = 1

    def __post_init__(self) -> None:
        # the default box follows the action's size: [0.2, 0.95]^3 with alpha_t (see action_low)
        size = self.action_size
        for name, bound in zip(("action_low", "action_high"), BUILTIN_ACTION_BOUNDS, strict=True):
            value = getattr(self, name)
            if size == 3 and isinstance(value, tuple | list) and tuple(value) == (bound, bound):
                object.__setattr__(self, name, (bound,) * 3)

    def validate(self) -> FoamEnvConfig:
        """Check every field; raise a one-line ``ValueError`` naming the first bad one. Returns self."""
        check_fields(self)
        return self

    @property
    def builtin(self) -> bool:
        """True for the built-in backward-facing step (``case_dir`` None)."""
        return self.case_dir is None

    @property
    def velocity_range(self) -> tuple[float, float] | None:
        """(low, high) of the per-episode inlet velocity (low == high for a fixed one); None: the
        user's case keeps its own inlet."""
        chosen = self.inlet_velocity
        if chosen is None:
            return BUILTIN_INLET_VELOCITY if self.builtin else None
        if isinstance(chosen, int | float) and not isinstance(chosen, bool):
            return float(chosen), float(chosen)
        if isinstance(chosen, str) or len(chosen) != 2:
            raise ValueError(f"FoamEnvConfig.inlet_velocity: expected a float or (low, high), got {chosen!r}")
        return float(chosen[0]), float(chosen[1])

    @property
    def height_range(self) -> tuple[float, float] | None:
        """(low, high) of the per-episode step height; None for a fixed height."""
        if isinstance(self.step_height, tuple | list):
            return float(self.step_height[0]), float(self.step_height[1])
        return None

    @property
    def fixed_height(self) -> float:
        """The step height of an episode without a drawn one: the fixed height, or the range's low."""
        chosen = self.height_range
        return float(self.step_height) if chosen is None else chosen[0]  # type: ignore[arg-type]

    @property
    def action_size(self) -> int:
        """Entries of an action: 2 (alpha_u, alpha_p), 3 with relax_k_omega="action" (alpha_t too)."""
        return 3 if self.relax_k_omega == K_OMEGA_ACTION else 2

    @property
    def variant(self) -> str | None:
        """The SIMPLE variant the bridge sets; None: the user's case keeps its own."""
        if self.simple_variant is None and self.builtin:
            return BUILTIN_SIMPLE_VARIANT
        return self.simple_variant

    @property
    def k_omega_relaxation(self) -> float | str | None:
        """The turbulence fields' factor the bridge sets (a float or FOLLOW_ALPHA_U); None: the case's own."""
        if self.relax_k_omega is None and self.builtin:
            return BUILTIN_RELAX_K_OMEGA
        return self.relax_k_omega

    @property
    def turbulence_check_factor(self) -> float | None:
        """The factor the convergence check relaxes (and judges) the turbulence fields at when the agent
        sets them: ``confirm_alpha_t`` where set and alpha_t is an action, else ``confirm_alpha_u``."""
        if self.confirm_alpha_t is not None and self.k_omega_relaxation == K_OMEGA_ACTION:
            return self.confirm_alpha_t
        return self.confirm_alpha_u

    @property
    def turbulence_formula(self) -> tuple[float, float] | None:
        """(intensity, nu_t/nu) for the inlet k/omega when the inlet speed is set; None: keep the case's."""
        if self.inlet_turbulence is None and self.builtin:
            return PAPER_INLET_TURBULENCE
        return None if self.inlet_turbulence is None else tuple(float(v) for v in self.inlet_turbulence)

    def with_absolute_paths(self) -> FoamEnvConfig:
        """This config with ``case_dir`` and ``work_dir`` resolved against the current directory.

        Workers (spawned processes, Ray actors on other nodes) and OpenFOAM (run with ``-case`` from
        inside the case) do not share the caller's working directory: relative paths must not travel.
        """
        return dataclasses.replace(self, case_dir=absolute_path(self.case_dir),
                                   work_dir=absolute_path(self.work_dir))

    @property
    def observed(self) -> tuple[str, ...]:
        """The fields the residual features observe, in order: ``observed_fields``, else the criterion's."""
        return tuple(self.convergence) if self.observed_fields is None else tuple(self.observed_fields)

    @property
    def observation_size(self) -> int:
        """Length of the observation vector: the state, the residual features, the progress, the action."""
        return (int(self.observe_state) + self.residual_features * len(self.observed)
                + int(self.observe_progress) + int(self.observe_algorithm)
                + self.action_size * int(self.observe_action) + int(self.observe_gain))

    # ---- JSON (the "foam" section of a train-foam run's config.json) ----------------------------------
    def to_json(self) -> dict[str, Any]:
        """Every field by name as JSON-ready values (tuples as lists, ``convergence`` as a plain dict,
        paths as strings); the inverse of :meth:`from_json`. ``observed_fields`` only when set: a config
        without it writes the JSON it always wrote (config.json, reference cache keys)."""
        return config_to_json(self)

    @classmethod
    def from_json(cls, data: Any) -> FoamEnvConfig:
        """The validated config of a :meth:`to_json` dict; one-line ValueError if bad.

        Fields missing from ``data`` take the defaults (a run written before a field existed still
        loads); the JSON lists of tuple fields (and of a velocity or height range) become tuples again.
        """
        values = config_values(data, [item.name for item in dataclasses.fields(cls)])
        try:
            return cls(**values).validate()
        except TypeError as err:  # e.g. a string where a number belongs, met inside validate()
            raise ValueError(f"foam config: {err}") from None


def without_convergence_test(cfg: FoamEnvConfig) -> FoamEnvConfig:
    """``cfg`` with every threshold of its criterion at NEVER_CONVERGED: the solver never stops itself."""
    return dataclasses.replace(cfg, convergence={name: NEVER_CONVERGED for name in cfg.convergence})


def failure_reward(cfg: FoamEnvConfig, iterations_before: int, cost_per_iteration: float = 1.0) -> float:
    """Reward of the step on which the solver failed (crashed, diverged, hung, dead worker).

    ``cfg.failure_penalty`` if set; otherwise as if the episode had run to the cap:
    ``-(max_iterations - iterations_before) * cost_per_iteration``, with ``iterations_before`` = K at the
    start of that step, so that with the "iterations" reward (cost 1 per iteration) the episode's
    return is ``-max_iterations``.
    """
    if cfg.failure_penalty is not None:
        return float(cfg.failure_penalty)
    return -float(max(cfg.max_iterations - iterations_before, 0)) * float(cost_per_iteration)


def cost_per_iteration(cfg: FoamEnvConfig, cost: float, iterations: int) -> float:
    """An episode's mean cost per SIMPLE iteration so far in the reward's unit, for :func:`failure_reward`
    (1 for the "iterations" reward, and before any iteration ran)."""
    if cfg.reward == "iterations" or iterations <= 0 or cost <= 0:
        return 1.0
    return cost / iterations


def absolute_path(path: Path | str | os.PathLike[str] | None) -> Path | None:
    """``path`` made absolute (symlinks resolved), ``~`` expanded; None stays None."""
    return None if path is None else Path(path).expanduser().resolve()
