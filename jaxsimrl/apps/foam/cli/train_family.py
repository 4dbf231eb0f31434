"""train-foam ``--family``: one controller trained on many cases (foam_bridge._family_env).

Each case keeps what is its own: criterion, action box (plain SIMPLE's is its own factors' neighbourhood,
foam_bridge._user_case), algorithm. What one controller needs to act on all of them is shared:

- the observation leaves out the flow state (its scale is one flow's, and a case may have no inlet) and
  observes the algorithm (1 for SIMPLEC), the residuals of one field per role (velocity, the first
  turbulence field, pressure: jaxsimrl.apps.foam.solve.fields), progress and the factors in force;
- the action is a share of each case's box (``action_share``), three factors (U, p, turbulence), with
  share 0.5 at ``action_pivot`` (jaxsimrl.apps.foam.solve.settings.around_own): the training family's
  constant for the case's algorithm, clipped into its box (a SIMPLEC case's alpha_u never below its own),
  so the initial policy starts where a user who copied that constant would;
- the reward is scaled per case by 100 / the cost of the case's own settings (their iterations, or their
  solver CPU seconds with ``--reward solver-time``), so that a case ten times longer than another does not
  outweigh it tenfold; and each case's budget is
  ``BUDGET_FACTOR`` x those iterations (a bad episode costs a bounded multiple of a good one), or the
  case's own budget where its own settings do not converge.

The own runs are measured here once, before the run starts (a progress line each), and the family's
configs are written into config.json, so a resumed run measures nothing again. A case that foam_bridge's
generator made (``jaxsimrl generate-cases``) is not run again: the generator ran its own settings when it
made it (to keep only cases they converge) and its manifest, ``generated.json`` beside the case, holds that
run; a family of thousands of generated cases pays its own runs once, on the generator's workers.
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from foam_bridge import FoamEnvConfig, check_case, find_openfoam, read_generated
from jaxsimrl.apps.foam.config import user_case_config
from jaxsimrl.apps.foam.solve.fields import observed_mapping
from jaxsimrl.apps.foam.solve.own import run_own
from jaxsimrl.apps.foam.solve.settings import around_own, check_factor, read_case_settings

#: Each case's iteration budget: this multiple of its own settings' iterations (rounded up to steps).
BUDGET_FACTOR = 3
#: A case's reward is -iterations x REWARD_UNIT / its own iterations: an episode as long as the case's own
#: returns -REWARD_UNIT.
REWARD_UNIT = 100.0
#: The observed fields by role (jaxsimrl.apps.foam.solve.fields maps them onto each case's own).
FAMILY_OBSERVED = ("U", "k", "p")
#: What every case of a family shares (besides the residual features, progress and action switches).
SHARED = {"observe_state": False, "observe_algorithm": True, "action_share": True,
          "relax_k_omega": "action", "observed_fields": FAMILY_OBSERVED, "action_low": (0.2,) * 3,
          "action_high": (0.95,) * 3}


def family_case_dirs(paths: Sequence[str | Path]) -> list[Path]:
    """The cases named: a case directory (it has system/controlDict) stands for itself, any other
    directory for the cases directly inside it (a family foam_bridge's generator wrote)."""
    found: list[Path] = []
    for path in (Path(p).expanduser().resolve() for p in paths):
        if (path / "system" / "controlDict").is_file():
            found.append(path)
        elif path.is_dir():
            found += sorted(p for p in path.iterdir()  # a hidden directory is a tool's scratch, not a case
                            if not p.name.startswith(".") and (p / "system" / "controlDict").is_file())
        else:
            raise ValueError(f"--family {path}: not a directory")
    if not found:
        raise ValueError(f"--family {' '.join(map(str, paths))}: no case (no directory with "
                         f"system/controlDict)")
    return found


def family_configs(cases: Sequence[Path], template: FoamEnvConfig,
                   say: Callable[[str], None]) -> dict[str, FoamEnvConfig]:
    """{case name: its config}: ``template``'s observation switches and interval, the shared settings
    above, and each case's own criterion, box, algorithm, budget and reward scale (its own run measured)."""
    openfoam, configs = find_openfoam(template.openfoam_path), {}
    names = _names(cases)
    recorded = _recorded_runs({case.parent for case in cases})
    with tempfile.TemporaryDirectory(prefix="jaxsimrl_family_") as scratch:
        for index, (name, case) in enumerate(zip(names, cases, strict=True)):
            cfg = dataclasses.replace(template, case_dir=str(case), **SHARED)
            work = Path(scratch) / f"case_{index}"
            info = check_case(case, cfg, openfoam, work)  # builds work/checked
            configs[name] = _case_config(cfg, case, (work / "checked", info), work / "own", say, name,
                                         recorded.get(case))
    return configs


def _case_config(cfg: FoamEnvConfig, case: Path, checked: tuple[Path, Any], own_dir: Path,
                 say: Callable[[str], None], name: str, recorded: OwnCost | None) -> FoamEnvConfig:
    """``cfg`` made the case's own (see family_configs); its own run: ``recorded`` (the generator's), else
    run in ``own_dir`` once the checks passed (a case that cannot join the family costs no run)."""
    settings, info = read_case_settings(case, 0), checked[1]
    confirm = None if cfg.confirm_alpha_u is None else check_factor(settings)  # as solve checks the case
    cfg = user_case_config(dataclasses.replace(cfg, simple_variant=settings.variant, confirm_alpha_u=confirm),
                           [], checked=checked)
    cfg = around_own(cfg, settings)
    mapping, why = observed_mapping(cfg, info.solved_fields)
    if mapping is None:
        raise ValueError(f"--family: case {case}: {why}")
    own = recorded or _run_own(case, own_dir)
    # a case its own settings do not converge keeps its own budget (the iterations they ran: its endTime)
    iterations = max(own.iterations, cfg.interval)
    budget = math.ceil((BUDGET_FACTOR if own.converged else 1) * iterations / cfg.interval) * cfg.interval
    budget = min(cfg.max_iterations, budget)
    cost = max(own.cpu_s, 1e-3) if cfg.reward == "solver-time" else iterations
    source = ", as the generator ran them" if own.recorded else ""
    say(f"family case {name}: {settings.variant}, own settings {'converge in' if own.converged else 'reach'}"
        f" {own.iterations} iterations ({own.cpu_s:.2f} s CPU{source}); budget {budget}")
    return dataclasses.replace(cfg, observed_fields=tuple(mapping.values()), max_iterations=budget,
                               reward_scale=REWARD_UNIT / cost).validate()


@dataclass(frozen=True)
class OwnCost:
    """What a case's own settings cost: converged, iterations, solver CPU seconds; ``recorded``: taken from
    the generator's manifest rather than run here."""

    converged: bool
    iterations: int
    cpu_s: float
    recorded: bool


def _recorded_runs(directories: set[Path]) -> dict[Path, OwnCost]:
    """{case: its own run} as the generator recorded them in each directory's ``generated.json`` (each
    manifest read once)."""
    return {directory / entry["name"]: OwnCost(bool(entry["converged"]), int(entry["iterations"]),
                                               float(entry["cpu_s"]), True)
            for directory in directories for entry in read_generated(directory).get("cases", [])
            if entry.get("iterations") is not None}


def _run_own(case: Path, own_dir: Path) -> OwnCost:
    """The case's own run, run now (a case no generator recorded)."""
    own = run_own(case, own_dir, "own", 24 * 3600.0)
    return OwnCost(own.converged, own.iterations, own.cpu_time_s, False)


def _names(cases: Sequence[Path]) -> list[str]:
    """Each case's directory name, with its parent's where two cases share one."""
    plain = [case.name for case in cases]
    return [f"{case.parent.name}/{case.name}" if plain.count(case.name) > 1 else case.name for case in cases]


def family_from_json(record: dict[str, Any]) -> dict[str, FoamEnvConfig]:
    """The family of a run's config.json (empty for a run of one case)."""
    return {name: FoamEnvConfig.from_json(data) for name, data in record.get("family", {}).items()}

