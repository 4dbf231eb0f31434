"""What ``solve`` runs a user's case with: the env config and the case's own factors and budget.

The MDP is the policy's (step interval, observation layout, what the actions mean, the fields whose
residuals it observes: the case's fields of the same roles, jaxsimrl.apps.foam.solve.fields), everything about
the case is the case's (its residualControl as the criterion unless ``--residual`` gives one,
jaxsimrl.apps.foam.solve.criterion; the action box its algorithm tolerates, its turbulence relaxation, its
inlet, its own iteration budget), and convergence is confirmed at a fixed relaxation (foam_bridge._confirm) so
that no unconverged field is reported as converged.
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from foam_bridge import (
    CaseError,
    FoamCaseEnv,
    FoamEnvConfig,
    NoResidualControl,
    check_case,
    check_case_files,
    copy_case,
    declared_patches,
    find_openfoam,
    foamdict,
    solved_field_names,
    time_directories,
)
from jaxsimrl.apps.foam.config import user_case_config
from jaxsimrl.apps.foam.solve.criterion import Residual, resolve, stop_only, stopping_function_objects
from jaxsimrl.apps.foam.solve.fields import observed_mapping

#: FoamEnvConfig fields that define the policy's MDP (observation, action meaning); copied when present.
POLICY_FIELDS = ("interval", "residual_features", "state_scale", "observe_progress", "observe_action",
                 "observe_gain", "scale_free_state", "observe_state", "observe_algorithm", "action_share",
                 "pivot_at", "action_radius")
#: The policy's turbulence setting that is part of its action (helper config: a third action).
TURBULENCE_ACTION = "action"
#: The iteration budget when the case's controlDict gives none (endTime / deltaT).
DEFAULT_MAX_ITERATIONS = 4000


@dataclass(frozen=True)
class CaseSettings:
    """The case's own (alpha_u, alpha_p, turbulence) factors (None where it sets none), whether its
    relaxationFactors are flat, its iteration budget (controlDict endTime / deltaT) and its algorithm
    ("SIMPLE", or "SIMPLEC" for ``consistent yes``)."""

    factors: tuple[float | None, float | None, float | None]
    flat: bool
    budget: int | None
    variant: str = "SIMPLE"


@dataclass(frozen=True)
class CheckedCase:
    """A user's case as solve's check built it (its directory, meshed, and its CaseInfo); called with
    ``(cfg, work_dir, env_id)`` it is the controlled run's env, which starts from that build. It travels
    to the worker process (foam_bridge's ``make_env``), so it stays a picklable module-level class."""

    directory: Path
    info: Any

    def __call__(self, cfg: FoamEnvConfig, work_dir: Path, env_id: int) -> Any:
        return FoamCaseEnv(cfg, work_dir=work_dir, env_id=env_id, base=(self.directory, self.info))


def start_of(case: Path, from_time: float | None = None) -> tuple[int, str]:
    """The time a solve of ``case`` starts from and how it was chosen: ``from_time`` (--from-time), else
    its latest time directory, as ``startFrom latestTime`` would (a partly converged run goes on from
    there). One-line ValueError for a time it does not have, or one that is not an integer (the bridge
    runs deltaT 1)."""
    times = [value for value, path in time_directories(case) if (path / "U").is_file()
             or (path / "U.gz").is_file() or value == 0]
    if from_time is not None and from_time not in times:
        raise ValueError(f"--from-time {from_time:g}: case {case} has no time directory {from_time:g} with "
                         f"fields (it has {', '.join(f'{value:g}' for value in times) or 'none'})")
    start = from_time if from_time is not None else max(times, default=0.0)
    if not float(start).is_integer():
        raise ValueError(f"case {case}: time {start:g} is not an integer; solve runs deltaT 1 from an "
                         f"integer time (give --from-time)")
    how = "--from-time" if from_time is not None else "latest" if start > 0 else ""
    return int(start), f"time {int(start)}" + (f" ({how})" if how else "")


def read_case_settings(case: Path, start_time: int = 0) -> CaseSettings:
    """Read the case's relaxation factors and budget as OpenFOAM expands them (on a scratch copy); the
    budget of a run from ``start_time`` > 0 is the case's endTime minus it."""
    openfoam = find_openfoam()
    with tempfile.TemporaryDirectory(prefix="jaxsimrl_solve_read_") as scratch:
        copy = Path(scratch) / "case"
        copy_case(case, copy, mesh=False)
        solution = foamdict.expand(openfoam, copy, "system/fvSolution")
        control = foamdict.expand(openfoam, copy, "system/controlDict")
    relaxation = solution.get("relaxationFactors", {})
    relaxation = relaxation if isinstance(relaxation, dict) else {}
    flat = bool(relaxation) and "fields" not in relaxation and "equations" not in relaxation
    equations = relaxation if flat else relaxation.get("equations", {}) or {}
    fields = relaxation if flat else relaxation.get("fields", {}) or {}
    factors = (_factor(equations, "U"), _factor(fields, "p"), _turbulence_factor(equations))
    simple = solution.get("SIMPLE", {})
    consistent = _is_true(simple.get("consistent", False)) if isinstance(simple, dict) else False
    if start_time:
        control = {**control, "startTime": start_time}
    return CaseSettings(factors, flat, _budget(control), "SIMPLEC" if consistent else "SIMPLE")


def _is_true(value: Any) -> bool:
    """An OpenFOAM switch (``yes``/``on``/``true``, as foamlib parses it or as text)."""
    return value is True or (isinstance(value, str) and value.lower() in ("yes", "on", "true", "y", "t"))


#: The inlet patch's name when a solve is given none (OpenFOAM's tutorials name it so).
DEFAULT_INLET = "inlet"


def not_applicable(policy_cfg: FoamEnvConfig, settings: CaseSettings,
                   solved: Sequence[str] = (), inlet: str | None = DEFAULT_INLET) -> str | None:
    """Why the controller does not apply to the case (None if it does): its factors were learned for one
    pressure-velocity algorithm and mean something else under the other (SIMPLEC tolerates alpha_p ~0.9,
    plain SIMPLE needs ~0.3: foam_bridge._user_case), so a controller trained on SIMPLEC is not used on a
    plain SIMPLE case, nor the reverse; and a controller that observes residuals needs a case field for
    each field it observes (jaxsimrl.apps.foam.solve.fields; ``solved``: the case's CaseInfo.solved_fields);
    and one that observes the flow state, scaled by the inlet's, needs an inlet (``inlet``: the solve's
    patch)."""
    trained = policy_cfg.variant if policy_cfg.case_dir is None else policy_cfg.simple_variant
    if getattr(policy_cfg, "observe_algorithm", False):  # trained on both: it reads which one the case uses
        trained = None
    if trained is not None and trained != settings.variant:
        return (f"the controller was trained on {trained} and the case uses {settings.variant}: its factors "
                f"do not transfer, so the case runs with its own settings")
    if inlet is None and getattr(policy_cfg, "observe_state", True):
        return (f"the controller observes the flow relative to the inlet's and the case has no patch named "
                f"{DEFAULT_INLET!r} (--inlet-patch NAME names its inlet), so the case runs with its own "
                f"settings")
    return observed_mapping(policy_cfg, solved)[1]


def _factor(tree: Any, name: str) -> float | None:
    try:
        value = foamdict.lookup(tree, name) if isinstance(tree, dict) else None
        value = value[-1] if isinstance(value, list | tuple) else value
        return float(value) if value is not None else None
    except (KeyError, TypeError, ValueError):
        return None


def _turbulence_factor(equations: Any) -> float | None:
    for name in ("k", "epsilon", "omega", "nuTilda"):
        found = _factor(equations, name)
        if found is not None:
            return found
    return None


def _budget(control: dict[str, Any]) -> int | None:
    try:
        end, start, delta = (float(control.get(key, default)) for key, default in
                             (("endTime", math.nan), ("startTime", 0.0), ("deltaT", 1.0)))
    except (TypeError, ValueError):
        return None
    steps = (end - start) / delta if delta > 0 else math.nan
    return int(round(steps)) if math.isfinite(steps) and steps >= 1 else None


def solve_config(case: Path, policy_cfg: FoamEnvConfig, work: Path, max_iterations: int,
                 confirm_alpha_u: float | None, action_box: tuple[Sequence[float], Sequence[float]] | None,
                 step_timeout_s: float, inlet_patch: str | None = None,
                 residual: Residual | str | None = None, start_time: int = 0,
                 settings: CaseSettings | None = None, confirm_alpha_t: float | None = None
                 ) -> tuple[FoamEnvConfig, CheckedCase]:
    """The env config of the controlled run (see the module docstring) and the case as its check built
    it (``work/checked`` and its CaseInfo: the controlled run's env starts from it instead of building
    and dry-running the case again); one-line CaseError/ValueError if the bridge cannot drive the case.
    ``residual``: the criterion instead of the case's residualControl (jaxsimrl.apps.foam.solve.criterion);
    ``start_time``: the case's time directory the run starts from (:func:`start_of`); ``inlet_patch``: the
    patch whose flow the controller observes (None: the case's ``inlet`` if it has one, else no inlet,
    :func:`inlet_of`); ``settings``: the case's own (:func:`read_case_settings`), read here if a policy
    that needs them (its algorithm observed, its action around the case's own factors) is not given them.

    Starting from the check's build is safe: the check builds exactly what the env would (the same
    copy, mesh and dry run, foam_bridge._base_case.check_case), from this config before the case's own
    criterion, box and observed fields are applied, and none enters the build (the dry run relaxes with
    the case's own factors, or the box's lower corner, which is the built-in one for a case without own
    factors). ``confirm_alpha_t``: the check's turbulence factor (FoamEnvConfig.confirm_alpha_t)."""
    copied = {name: getattr(policy_cfg, name) for name in POLICY_FIELDS if hasattr(policy_cfg, name)}
    if getattr(policy_cfg, "relax_k_omega", None) == TURBULENCE_ACTION:
        copied["relax_k_omega"] = TURBULENCE_ACTION
    pivoted = getattr(policy_cfg, "action_pivot", None) is not None  # it acts around the case's own factors
    if settings is None and (copied.get("observe_algorithm") or pivoted):
        settings = read_case_settings(case, start_time)
    if copied.get("observe_algorithm"):  # it observes which one: the case's own, written out as it is
        copied["simple_variant"] = settings.variant
    interval = min(copied.get("interval", 100), max_iterations)
    inlet_patch = inlet_of(case, inlet_patch, find_openfoam(policy_cfg.openfoam_path))
    cfg = FoamEnvConfig(**{**copied, "interval": interval}, case_dir=case, max_iterations=max_iterations,
                        confirm_alpha_u=confirm_alpha_u, confirm_alpha_t=confirm_alpha_t, work_dir=work,
                        keep_cases=True, step_timeout_s=step_timeout_s, inlet_patch=inlet_patch,
                        start_time=start_time)
    explicit: list[str] = []
    if action_box is not None:
        cfg = dataclasses.replace(cfg, action_low=tuple(action_box[0]), action_high=tuple(action_box[1]))
        explicit = ["action_low", "action_high"]
    check_case_files(case, cfg, need_mesh=False)  # a wrong path says so, OpenFOAM or not
    info = check_case(case, cfg, find_openfoam(cfg.openfoam_path), work)
    checked = CheckedCase(work / "checked", info)
    try:
        cfg = user_case_config(cfg, explicit + ["convergence"] * (residual is not None),
                               checked=(checked.directory, checked.info))
    except NoResidualControl as err:  # train-foam's hint names its --config; solve has a flag
        cfg = _stopped_by_the_case(cfg, explicit, checked, err.where)
    if residual is not None:
        criterion = resolve(residual, solved_field_names(info.solved_fields), case)
        cfg = dataclasses.replace(cfg, convergence=criterion).validate()
    if pivoted:
        cfg = around_own(cfg, settings).validate()
    mapping, _ = observed_mapping(policy_cfg, info.solved_fields)  # no mapping: not_applicable says why
    if mapping is not None:
        cfg = dataclasses.replace(cfg, observed_fields=tuple(mapping.values())).validate()
    return cfg, checked


def inlet_of(case: Path, named: str | None, openfoam: Any) -> str | None:
    """The inlet patch a solve observes: ``named`` (--inlet-patch), which the case must have; else the
    case's patch ``inlet``, or None for a case without one (a cavity, a closed mixer: the rules run it, and
    a controller that observes the inlet's flow does not apply, :func:`not_applicable`)."""
    patches = declared_patches(case, openfoam)
    if named is None:
        return DEFAULT_INLET if patches is None or DEFAULT_INLET in patches else None
    if patches is not None and named not in patches:
        raise ValueError(f"--inlet-patch {named}: case {case} has no patch named {named!r} (its patches: "
                         f"{', '.join(patches)})")
    return named


def _stopped_by_the_case(cfg: FoamEnvConfig, explicit: list[str], checked: CheckedCase, where: Any
                         ) -> FoamEnvConfig:
    """``cfg`` of a case without residualControl: its runTimeControl's criterion alone
    (jaxsimrl.apps.foam.solve.criterion) and its own box; else a one-line CaseError naming --residual."""
    controls = foamdict.expand(find_openfoam(cfg.openfoam_path), checked.directory, "system/controlDict")
    if not stopping_function_objects(controls):
        raise CaseError(f"{where}: SIMPLE has no residualControl (nor a runTimeControl function object that "
                        f"ends the run), so simpleFoam never stops converged: give a criterion with "
                        f"--residual (1e-4 for every field, or p=1e-3,U=1e-4)")
    cfg = user_case_config(cfg, [*explicit, "convergence"], checked=(checked.directory, checked.info))
    return dataclasses.replace(cfg, convergence=stop_only(solved_field_names(checked.info.solved_fields)))


#: solve's default convergence check: at the case's own alpha_u (:func:`check_factor`).
OWN_CHECK = "own"
#: The check's alpha_u for a case that does not relax U (or relaxes it at 1, where SIMPLEC's check breaks
#: down): the factor the learned controllers were checked at.
UNRELAXED_CHECK = 0.9


def check_factor(settings: CaseSettings) -> float:
    """The convergence check's alpha_u for a case (foam_bridge._confirm): its own alpha_u, so that a
    controlled run is held to exactly the normalisation the case's own criterion reads at the user's own
    factors (a controller that ends at a lower alpha_u than the case's cannot converge by relaxation
    alone, and one at a higher alpha_u was held to a stricter test already); :data:`UNRELAXED_CHECK` when
    the case does not relax U. A fixed 0.9 failed plain-SIMPLE cases converged at their own 0.7: on
    airFoil2D, U reads 2.3e-5 at 0.9 from fields the solver reads 6.9e-6 at 0.7 (criterion 1e-5)."""
    own = settings.factors[0]
    return own if own is not None and 0 < own < 1 else UNRELAXED_CHECK


def turbulence_check(settings: CaseSettings) -> float | None:
    """The convergence check's factor for the turbulence fields of a controller that sets alpha_t
    (FoamEnvConfig.confirm_alpha_t): the case's own turbulence factor, as :func:`check_factor` takes its
    own alpha_u; None (the check's alpha_u) when the case sets none. Checked at the own alpha_u instead,
    a SIMPLEC case whose own turbulence factor is below its alpha_u failed the check at its own factors."""
    own = settings.factors[2]
    return own if own is not None and 0 < own <= 1 else None


def unrelaxed_as_one(settings: CaseSettings) -> list[float]:
    """The case's own (alpha_u, alpha_p, turbulence), 1 for a factor it does not set (no relaxation)."""
    return [1.0 if value is None else value for value in settings.factors]


#: The training family's best constant (alpha_u, alpha_p, turbulence) per algorithm: the triple with the
#: lowest geometric mean over the 8 training variants of each algorithm of (iterations / the variant's best
#: run) among 8 triples each (experiments/controller/family-constant/family_best.json: 1.06 plain SIMPLE,
#: 1.17 SIMPLEC; 0.64-0.77x the own settings but on one variant, pitzDaily-2, where SIMPLEC's stalls). The
#: constant a user would copy from our docs, the baseline a learned controller must beat, and where one
#: starts (``around_own``).
FAMILY_CONSTANT = {"SIMPLE": (0.8, 0.3, 0.9), "SIMPLEC": (0.95, 1.0, 0.95)}
#: A SIMPLEC case's box for a controller acting around its own factors: (alpha_u, alpha_p, turbulence) at
#: most ``SIMPLEC_TOP`` (or the case's own where higher) ...
SIMPLEC_TOP = (0.95, 1.0, 0.95)
#: ... and at least the case's own alpha_u (below it SIMPLEC with an unrelaxed pressure is unstable, not
#: cautious: T3A-0 at its own 0.9 converges in 278 iterations, at 0.85 diverges at iteration 351, at 0.8 at
#: 49; experiments/controller/family-v5-setup/t3a_floor.json) and ``SIMPLEC_FLOOR`` for p and turbulence.
SIMPLEC_FLOOR = 0.5


def around_own(cfg: FoamEnvConfig, settings: CaseSettings) -> FoamEnvConfig:
    """The box a controller acting in shares of a case's neighbourhood gets, and its ``action_pivot`` (the
    factors at share 0.5): the training family's constant for the case's algorithm (``FAMILY_CONSTANT``),
    clipped into the box, so that the initial policy starts where a user who copied that constant would
    and learns where to leave it; with ``cfg.pivot_at`` "own", the case's own factors (the initial policy
    is then the user's own run: on generated plain SIMPLE cases the family's constant cost up to 4.5x own
    or never converged, experiments/controller/generated-ranking/). Plain SIMPLE: the case's box (around
    its own factors, foam_bridge's user_case) widened to hold its own factors. SIMPLEC: from the case's
    own alpha_u (``SIMPLEC_FLOOR`` for the others) to ``SIMPLEC_TOP`` (0.98 converged no SIMPLEC training
    variant within 3x its own: experiments/controller/family-v6-setup/simplec_top.json), whose top is its
    family constant: it learns where to go down."""
    own = unrelaxed_as_one(settings)[:cfg.action_size]
    if settings.variant == "SIMPLEC":
        high = tuple(max(top, factor) for top, factor in zip(SIMPLEC_TOP, own, strict=False))
        floors = (own[0], *(SIMPLEC_FLOOR for _ in own[1:]))
        low = tuple(min(floor, factor, top) for floor, factor, top in zip(floors, own, high, strict=True))
    else:
        low = cfg.action_low
        high = tuple(max(hi, factor) for hi, factor in zip(cfg.action_high, own, strict=True))
    constant = own if cfg.pivot_at == "own" else FAMILY_CONSTANT[settings.variant][:cfg.action_size]
    pivot = tuple(min(max(factor, lo), hi) for factor, lo, hi in zip(constant, low, high, strict=True))
    return dataclasses.replace(cfg, action_low=low, action_high=high, action_pivot=pivot)


#: How far from the case's own alpha_u the spread run (``--compare``) relaxes U: a change a user makes
#: without a second thought, whose converged answer is as legitimate as the own run's.
SPREAD_NUDGE = 0.05


def nudged_factors(settings: CaseSettings) -> tuple[tuple[float, float, float], str]:
    """The spread run's constant factors (the case's own, alpha_u moved by ``SPREAD_NUDGE`` the way its
    algorithm tolerates: SIMPLEC up, as SIMPLEC with an unrelaxed pressure goes unstable below its own
    alpha_u (T3A: see SIMPLEC_FLOOR's note), plain SIMPLE down; U unrelaxed: 1 - SPREAD_NUDGE) and how to
    say it ("alpha_u 0.85")."""
    u, p, t = unrelaxed_as_one(settings)
    up = settings.variant == "SIMPLEC" and u + SPREAD_NUDGE <= SIMPLEC_TOP[0] + 1e-9
    nudged = round(u + SPREAD_NUDGE if up else min(u, 1.0) - SPREAD_NUDGE, 4)
    return (nudged, p, t), f"alpha_u {nudged:g}"


def with_own(cfg: FoamEnvConfig, settings: CaseSettings) -> FoamEnvConfig:
    """``cfg`` with its box widened to hold the case's own factors (a factor the case does not set: 1), so
    that "the case's own factors" a rule or the watchdog goes back to are exactly the user's: a SIMPLEC
    case with an unrelaxed pressure is run at p 1, not at the box's top 0.95."""
    size = len(cfg.action_low)
    own = unrelaxed_as_one(settings)[:size]
    low = tuple(min(lo, factor) for lo, factor in zip(cfg.action_low, own, strict=True))
    high = tuple(max(hi, factor) for hi, factor in zip(cfg.action_high, own, strict=True))
    return dataclasses.replace(cfg, action_low=low, action_high=high).validate()


def own_action(settings: CaseSettings, cfg: FoamEnvConfig, size: int) -> list[float]:
    """The case's own factors as an action of ``size`` entries, in the env's box (a factor the case does not
    set means no relaxation: 1, clipped to the box's top)."""
    own = unrelaxed_as_one(settings)[:size]
    low, high = list(cfg.action_low), list(cfg.action_high)
    return [min(max(value, lo), hi) for value, lo, hi in zip(own, low, high, strict=False)]


def observation_factor(policy_cfg: FoamEnvConfig, inlet_speed: float) -> float:
    """What the observed state is multiplied by so that the case's inlet speed reads as the middle of the
    policy's training range (1 when the policy's state is scale-free or either speed is unknown)."""
    if getattr(policy_cfg, "scale_free_state", False) or not getattr(policy_cfg, "observe_state", True) \
            or not (math.isfinite(inlet_speed) and inlet_speed > 0):
        return 1.0
    try:
        trained = policy_cfg.velocity_range
    except ValueError:
        return 1.0
    if trained is None:
        return 1.0
    middle = 0.5 * (trained[0] + trained[1])
    return (middle / inlet_speed) ** 2
