"""FoamEnvConfig.settle: the answer monitor of ``solve --settle`` ends a foam_bridge episode whose answer
has settled, on the coarse step (a user's case) with a criterion it never meets and the real simpleFoam."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from foam_marks import OPENFOAM
from test_solve import _coarse_step

from foam_bridge import FoamCaseEnv, FoamEnvConfig

pytestmark = OPENFOAM
NEVER = {"U": 1e-12, "p": 1e-12, "k": 1e-12, "omega": 1e-12}


def _episode(case: Path, work: Path, settle: float | None) -> tuple[list[str], dict]:
    cfg = FoamEnvConfig(case_dir=case, interval=100, max_iterations=1500, work_dir=work, settle=settle,
                        convergence=NEVER).validate()
    outcomes, info = [], {}
    with FoamCaseEnv(cfg) as env:
        env.reset(seed=0)
        own = np.full(env.action_space_spec.shape, 0.5)  # the middle of the box, held: a constant run
        done = False
        while not done:
            _, reward, done, truncated, info = env.step(own)
            assert np.isfinite(reward) and not truncated
            outcomes.append(info["outcome"])
    return outcomes, info


@pytest.mark.slow  # two episodes of the coarse step, one to its 1,500 iterations (~40 s)
def test_an_episode_ends_where_its_answer_settles_and_settle_none_runs_on(tmp_path: Path) -> None:
    case = _coarse_step(tmp_path / "step")
    outcomes, info = _episode(case, tmp_path / "settle", 1e-3)
    # at the box's middle the coarse step's answer cycles about a steady mean: either ends the episode
    assert outcomes[-1] in ("settled", "oscillating") and set(outcomes[:-1]) <= {"running"}
    assert info["iterations"] < 1500 and f"the answer {outcomes[-1]}" in info["cause"]
    assert info["episode"]["outcome"] == outcomes[-1]
    outcomes, info = _episode(case, tmp_path / "plain", None)  # off by default: runs to its budget
    assert outcomes[-1] == "truncated" and info["iterations"] == 1500


def test_settle_is_a_tolerance_or_none() -> None:
    assert FoamEnvConfig().settle is None
    with pytest.raises(ValueError, match="settle"):
        FoamEnvConfig(settle=0.0).validate()
    assert FoamEnvConfig(settle=1e-3).validate().settle == 1e-3
