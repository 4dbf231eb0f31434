"""The convergence check that relaxation cannot move (``FoamEnvConfig.confirm_alpha_u``).

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

simpleFoam's residualControl reads each equation's initial residual normalised by the *relaxed*
matrix. Relaxing the momentum equation with alpha_u divides its diagonal by alpha_u and adds the same
amount times the old field to the source, so the unnormalised residual of the old field is unchanged
while the normalisation grows: a lower alpha_u lowers the residual the criterion reads, at once, with
the field where it was. On the backward-facing step that is enough to "converge" a run far from the
solution (experiments/foam/README.md).

The check normalises at one fixed relaxation instead: one SIMPLE iteration from the run's own fields (a
scratch copy of the case at iteration K, started from its latest time) with alpha_u =
``confirm_alpha_u``, the step's alpha_p and the case's turbulence factor, whose initial residuals are
read from its log. When the turbulence factor is the agent's (alpha_t, or alpha_u that it follows), the
agent can move the k/omega residuals the same way: the check then relaxes them at ``confirm_alpha_u`` too
(at ``confirm_alpha_t`` when it is set and alpha_t is an action: solve sets the case's own turbulence
factor, the normalisation the user's own run reads), and checks them when the step relaxed them *below*
that factor. A policy trained with the step's alpha_t in the
check learned to drop alpha_t to ~0.3 on its last step (experiments/controller/README.md). A step at a
factor >= ``confirm_alpha_u`` was held by the solver's own test to a normalisation at least as strict as
the check's (U at 0.95 reads 0.83-0.88 x at 0.9), so nothing was gained and they are not re-read: a
restart of kOmegaSSTLM (OpenFOAM v1912) solves k before it recomputes gammaIntEff, which it neither
writes nor reads, so its first k solve runs without production and every restart of T3A reads k ~3e-2
and ReThetat ~4e-2 at 0.9 from fields whose own k residual is 1e-6 to 1e-8 (k 1.5e-3 even at 0.3):
checked there, no run could pass. The initial U residual of that iteration is computed from the
fields of K before anything is solved, so the check measures the run's state, not a step of its own. It
passes when the fields whose normalisation the agent lowered (:func:`_checked_fields`) meet the criterion.
Measured on the full mesh (test criterion): runs with alpha_u near 0.95 read 0.83-0.88 x their own U
residual at 0.9; random factors that met the criterion read 1.3-6.7 x the threshold
(experiments/foam/README.md).

A check and a restart read the fields the solver wrote, so a user's case is then written with
``writePrecision 17`` (its own format): rounded fields would read as residuals of their own.
"""

from __future__ import annotations

import shutil
import subprocess
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from foam_bridge import _episode_case as episode_case
from foam_bridge._config import FOLLOW_ALPHA_U, K_OMEGA_ACTION, FoamEnvConfig
from foam_bridge._logparse import LogParser, field_residual
from foam_bridge._openfoam import OpenFOAM
from foam_bridge._solver import run_to_end

__all__ = ["CHECK_DIR", "Confirmation", "confirm", "meets", "step_turbulence_factor"]

#: Directory of the check's scratch case, next to the episode case.
CHECK_DIR = "confirm"
#: A step factor this close under ``confirm_alpha_u`` counts as equal: float32(0.9) is 0.89999998, and
#: a normalisation 1e-7 looser gains nothing.
_FACTOR_TOLERANCE = 1e-6


@dataclass(frozen=True)
class Confirmation:
    """One check: the iteration K it tested, whether the checked fields (:func:`_checked_fields`) met
    the criterion, all residuals at the check's relaxation, the solver's residuals at K, the check's
    wall seconds, and what went wrong if the check itself could not run (then ``passed`` is False)."""

    iteration: int
    passed: bool
    residuals: dict[str, float] = field(default_factory=dict)
    solver_residuals: dict[str, float] = field(default_factory=dict)
    wall_time_s: float = 0.0
    error: str = ""

    def record(self) -> dict[str, object]:
        """The check as it appears in an episode record's "confirmations"."""
        entry: dict[str, object] = {"iteration": self.iteration, "passed": self.passed,
                                    "residuals": self.residuals, "solver_residuals": self.solver_residuals,
                                    "wall_time_s": round(self.wall_time_s, 3)}
        if self.error:
            entry["error"] = self.error
        return entry


def meets(cfg: FoamEnvConfig, residuals: dict[str, float], fields: Sequence[str] | None = None) -> bool:
    """Whether the criterion holds for ``fields`` (default all of it): as simpleFoam's own test, over
    the fields the case solves (a Spalart-Allmaras case has no k or omega); False without any."""
    solved = [name for name in (cfg.convergence if fields is None else fields)
              if name in cfg.convergence and name in residuals]
    return bool(solved) and all(residuals[name] <= cfg.convergence[name] for name in solved)


def step_turbulence_factor(cfg: FoamEnvConfig, alpha: Sequence[float]) -> float | None:
    """The factor a step's action ``alpha`` relaxed the turbulence fields with when the agent sets it:
    alpha_u when they follow it, alpha_t when it is an action (episode_case.turbulence_factor); None
    when it is the case's or a fixed one."""
    if cfg.k_omega_relaxation not in (FOLLOW_ALPHA_U, K_OMEGA_ACTION):
        return None
    factor = episode_case.turbulence_factor(cfg, alpha[0], alpha[2] if len(alpha) > 2 else None)
    return None if factor is None else float(factor)


def _checked_fields(cfg: FoamEnvConfig, turbulence: Sequence[str] | None = None,
                    step_factor: float | None = None) -> tuple[str, ...]:
    """The fields whose normalisation the agent lowered: the velocity, and the turbulence fields
    (``turbulence``, default ``cfg.turbulence_fields``) when they follow alpha_u or alpha_t is an action
    and the step relaxed them below ``confirm_alpha_u`` (``step_factor``, see
    :func:`step_turbulence_factor`; None: not known, checked). The others (p, turbulence at the case's
    factor or at one >= the check's) the solver's own test has met already, at least as strictly;
    re-reading them after a change of relaxation measures the change, not the run (on airFoil2D, plain
    SIMPLE, p reads 5.7e-2 at alpha_u 0.9 from fields converged to 1e-6 at 0.7; on T3A, see above)."""
    if cfg.k_omega_relaxation not in (FOLLOW_ALPHA_U, K_OMEGA_ACTION):
        return (cfg.velocity_field,)
    check = cfg.turbulence_check_factor
    if step_factor is not None and check is not None and step_factor >= check - _FACTOR_TOLERANCE:
        return (cfg.velocity_field,)
    return (cfg.velocity_field, *(cfg.turbulence_fields if turbulence is None else turbulence))


def confirm(episode: Path, base: Path, cfg: FoamEnvConfig, openfoam: OpenFOAM, iteration: int,
            alpha_p: float, solver_residuals: dict[str, float], flat: bool = False,
            turbulence: Sequence[str] | None = None, step_factor: float | None = None) -> Confirmation:
    """Check the fields the episode case wrote at ``iteration`` at alpha_u = ``cfg.confirm_alpha_u``
    (``flat``: the case's relaxationFactors use the old flat layout; ``turbulence``: the fields alpha_t
    relaxes when it is an action, see case.relaxation_text). When alpha_t is an action they are relaxed
    at ``cfg.turbulence_check_factor``, whatever the step's alpha_t was; otherwise at the env's fixed
    factor.
    ``step_factor``: the step's own turbulence factor (:func:`step_turbulence_factor`), which decides
    whether they are checked (:func:`_checked_fields`)."""
    assert cfg.confirm_alpha_u is not None
    started = time.monotonic()
    scratch = episode.parent / CHECK_DIR
    # the third factor is read only with alpha_t an action (relaxation_text): the agent's own is not used
    fixed = cfg.confirm_alpha_u
    text = episode_case.relaxation_text(cfg, fixed, alpha_p, flat, cfg.turbulence_check_factor, turbulence)
    parser = LogParser(episode_case.CELLS_FUNCTION, episode_case.INLET_FUNCTION, cfg.divergence_threshold)
    error = ""
    try:
        episode_case.write_check_case(episode, base, scratch, cfg, iteration, text, openfoam)
        code, _ = run_to_end(scratch, openfoam, parser, cfg.step_timeout_s)
        if code != 0 or not parser.history:
            error = f"the check's simpleFoam exited with code {code}: {parser.error or 'no iteration ran'}"
    except (OSError, ValueError, subprocess.TimeoutExpired) as err:  # e.g. a missing time directory
        error = f"the check could not run: {err}"
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    first = parser.history[0] if parser.history else {}
    found = {name: field_residual(first, name) for name in cfg.convergence}
    residuals = {name: float(value) for name, value in found.items() if value is not None}
    passed = not error and meets(cfg, residuals, _checked_fields(cfg, turbulence, step_factor))
    return Confirmation(iteration, passed, residuals, dict(solver_residuals),
                        time.monotonic() - started, error)
