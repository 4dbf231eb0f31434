"""A user's own case, as a CFD user first tries it (issue #16, section 3): a case that cannot run with its
own settings fails at creation in one line with OpenFOAM's message; a user's case brings its own MDP (its
residualControl, an action box its algorithm tolerates); flags of the built-in geometry are refused."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from foam_marks import needs_openfoam

from foam_bridge._base_case import own_factors
from foam_bridge._config import FoamEnvConfig
from foam_bridge._env import FoamCaseEnv
from foam_bridge._errors import CaseError
from foam_bridge._openfoam import find_openfoam
from foam_bridge._user_case import BUILTIN_BOX
from foam_bridge.foamdict import expand
from jaxsimrl.apps.foam.config import foam_config_from_json, foam_config_to_json
from jaxsimrl.cli.main import main

TUTORIALS = Path("/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam")
needs_tutorials = pytest.mark.skipif(not TUTORIALS.is_dir(), reason="openfoam-examples not installed")
#: Typos a user makes in fvSolution that foamDictionary reads past and simpleFoam does not.
TYPOS = {
    "unknown solver": ("solver          GAMG;", "solver          GAMGG;",
                       "Unknown symmetric matrix solver type GAMGG"),
    "missing semicolon": ("relTol          0.1;", "relTol          0.1", "excess tokens"),
}


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    try:
        code = main(["train-foam", *argv])
    except SystemExit as exit_:
        code = exit_.code
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _broken_pitz_daily(tmp_path: Path, typo: str) -> Path:
    old, new, _ = TYPOS[typo]
    case = tmp_path / "myCase"
    shutil.copytree(TUTORIALS / "pitzDaily", case)
    solution = case / "system" / "fvSolution"
    text = solution.read_text()
    assert old in text
    solution.write_text(text.replace(old, new, 1))
    expand(find_openfoam(), case, "system/fvSolution")  # foamDictionary reads it: only a run can tell
    return case


@needs_openfoam
@needs_tutorials
@pytest.mark.parametrize("typo", sorted(TYPOS))
def test_a_case_that_cannot_run_its_own_settings_fails_at_env_creation(tmp_path: Path, typo: str) -> None:
    case = _broken_pitz_daily(tmp_path, typo)
    cfg = FoamEnvConfig(case_dir=case, interval=50, max_iterations=100, work_dir=tmp_path / "work")
    with pytest.raises(CaseError) as raised:
        FoamCaseEnv(cfg)
    message = str(raised.value)
    assert "\n" not in message and message.startswith(f"case {case}: ")
    assert TYPOS[typo][2] in message and f"file: {case}/system/fvSolution" in message  # OpenFOAM's own words
    assert not (tmp_path / "work" / "env_0").exists()


@needs_openfoam
@needs_tutorials
def test_train_foam_refuses_a_broken_case_in_one_line_before_creating_the_run(capsys, tmp_path: Path) -> None:
    case = _broken_pitz_daily(tmp_path, "unknown solver")
    code, _, err = run_cli(capsys, "--case", str(case), "--episodes", "2", "--num-envs", "1",
                           "--max-iterations", "100", "--out", str(tmp_path / "run"))
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert TYPOS["unknown solver"][2] in err and not (tmp_path / "run").exists()


@pytest.mark.parametrize("flag, value", [("--mesh-scale", "0.5"), ("--step-height", "0.0254")])
def test_flags_of_the_built_in_geometry_are_refused_for_a_users_case(capsys, tmp_path, flag, value) -> None:
    case = tmp_path / "myCase"
    case.mkdir()  # refused before the case is even looked at
    code, out, err = run_cli(capsys, "--case", str(case), flag, value, "--print-config",
                             "--out", str(tmp_path / "run"))
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert f"{flag} applies to the built-in backward-facing step only" in err
    section = tmp_path / "config.json"
    section.write_text(json.dumps({"foam": {flag[2:].replace("-", "_"): float(value)}}))
    code, _, err = run_cli(capsys, "--case", str(case), "--config", str(section), "--print-config")
    assert code == 2 and "applies to the built-in backward-facing step only" in err


def _printed_foam_config(capsys, *argv: str) -> dict:
    code, out, err = run_cli(capsys, *argv, "--print-config")
    assert code == 0, err
    return json.loads(out)["foam"]


@needs_openfoam
@needs_tutorials
def test_a_users_case_keeps_its_own_criterion_and_gets_a_box_around_its_own_factors(capsys, tmp_path) -> None:
    """pitzDailyExptInlet: plain SIMPLE, k-epsilon, residualControl p, U and "(k|epsilon|omega)"."""
    case = TUTORIALS / "pitzDailyExptInlet"
    own = expand(find_openfoam(), case, "system/fvSolution")
    control = own["SIMPLE"]["residualControl"]
    foam = _printed_foam_config(capsys, "--case", str(case))
    # every field it lists with its own threshold; the pattern stands for the fields k-epsilon solves
    pattern = control['"(k|epsilon|omega)"']
    assert foam["convergence"] == {"p": control["p"], "U": control["U"], "epsilon": pattern, "k": pattern}
    alpha_u, alpha_p = own_factors(own["relaxationFactors"], FoamEnvConfig())
    assert foam["action_low"] == pytest.approx([alpha_u / 2, alpha_p / 2])
    assert foam["action_high"] == pytest.approx([min(1.25 * alpha_u, 0.95), min(1.25 * alpha_p, 0.95)])
    assert foam["action_low"] < [alpha_u, alpha_p] < foam["action_high"]  # its own factors are inside
    # a criterion or box set explicitly is kept; what config.json holds loads with the same meaning
    section = tmp_path / "config.json"
    explicit = {"convergence": {"U": 1e-3, "p": 5e-2}, "action_low": [0.3, 0.2]}
    section.write_text(json.dumps({"foam": explicit}))
    foam = _printed_foam_config(capsys, "--case", str(case), "--config", str(section))
    assert foam["convergence"] == {"U": 1e-3, "p": 5e-2}
    assert (foam["action_low"], foam["action_high"]) == ([0.3, 0.2], list(FoamEnvConfig().action_high))
    assert foam_config_to_json(foam_config_from_json(foam)) == foam


@needs_openfoam
@needs_tutorials
def test_a_simplec_case_keeps_the_built_in_box(capsys) -> None:
    foam = _printed_foam_config(capsys, "--case", str(TUTORIALS / "pitzDaily"))  # consistent yes
    assert (tuple(foam["action_low"]), tuple(foam["action_high"])) == BUILTIN_BOX
    assert set(foam["convergence"]) == {"p", "U", "k", "epsilon"}


@needs_openfoam
@needs_tutorials
def test_a_case_without_residual_control_is_refused_in_one_line(capsys, tmp_path) -> None:
    case = tmp_path / "myCase"
    shutil.copytree(TUTORIALS / "pitzDaily", case)
    solution = case / "system" / "fvSolution"
    text = solution.read_text()
    start = text.index("    residualControl")
    solution.write_text(text[:start] + text[text.index("}", start) + 1:])
    code, out, err = run_cli(capsys, "--case", str(case), "--print-config")
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert f"{solution}: SIMPLE has no residualControl" in err
    config = tmp_path / "config.json"  # with a criterion of its own it is fine
    config.write_text(json.dumps({"foam": {"convergence": {"U": 1e-3, "p": 5e-2}}}))
    foam = _printed_foam_config(capsys, "--case", str(case), "--config", str(config))
    assert foam["convergence"] == {"U": 1e-3, "p": 5e-2}


@pytest.mark.slow  # real runs
@needs_openfoam
@needs_tutorials
def test_the_own_box_of_a_plain_simple_case_avoids_the_sigfpe_of_the_built_in_box(tmp_path: Path) -> None:
    """pitzDailyExptInlet at the top corner of each box: the built-in box's (0.95, 0.95) dies of SIGFPE
    within a few dozen iterations, its own box's top corner runs on (measured: to the 2,000 cap)."""
    from jaxsimrl.apps.foam.config import user_case_config

    base = FoamEnvConfig(case_dir=TUTORIALS / "pitzDailyExptInlet", interval=100, max_iterations=300,
                         work_dir=tmp_path / "work")
    own = user_case_config(base, explicit=())
    outcomes = {}
    for name, cfg in (("built-in", base), ("own", own)):
        with FoamCaseEnv(cfg) as env:
            env.reset(seed=0)
            while True:
                _, _, terminated, truncated, info = env.step(cfg.action_high)
                if terminated or truncated:
                    outcomes[name] = (info["outcome"], info["cause"])
                    break
    assert outcomes["built-in"][0] == "crashed" and "SIGFPE" in outcomes["built-in"][1]
    assert outcomes["own"][0] in ("converged", "truncated")


def _rows(outcome: str, iterations: list[int], cause: str = "crashed at iteration 1: FOAM FATAL ERROR: x"):
    return [{"outcome": outcome, "iterations": k, "cause": cause if outcome != "converged" else ""}
            for k in iterations]


def test_systematic_failure_needs_every_episode_failed_the_same_way_and_one_per_env() -> None:
    from jaxsimrl.apps.foam.episodes import SYSTEMATIC_MIN_EPISODES, EpisodeLog

    def log(rows):
        return EpisodeLog(Path("unused.csv"), rows)

    same = _rows("crashed", [1] * 4)
    assert log(same).systematic_failure(num_envs=4) == f"at iteration 1: {same[0]['cause']}"
    assert log(same).systematic_failure(num_envs=5) is None  # one env has not ended an episode yet
    assert log(same[:SYSTEMATIC_MIN_EPISODES - 1]).systematic_failure(num_envs=1) is None
    assert log(same + _rows("converged", [400])).systematic_failure(num_envs=4) is None
    assert log(_rows("crashed", [1, 1, 1, 37])).systematic_failure(num_envs=4) is None  # a policy's SIGFPEs
    capped = _rows("truncated", [200] * 4, cause="")
    assert log(capped).systematic_failure(num_envs=4) is None  # not a failure


@pytest.mark.slow  # a real train-foam run
@needs_openfoam
def test_a_run_whose_episodes_all_fail_the_same_way_stops_non_zero_and_resumable(capsys, tmp_path) -> None:
    """Every episode of the built-in case 'diverges' at iteration 1 under an absurd divergence threshold:
    the run stops after its first update with the cause in one line, exit 1, and resumes (to stop again
    while the cause is there)."""
    from jaxsimrl.apps.foam.episodes import EpisodeLog

    config = tmp_path / "config.json"
    config.write_text(json.dumps({"foam": {"divergence_threshold": 1e-9}}))
    run = tmp_path / "run"
    code, _, err = run_cli(capsys, "--mesh-scale", "0.4", "--num-envs", "2", "--pool", "2",
                           "--steps-per-update", "8", "--max-iterations", "200", "--episodes", "40",
                           "--config", str(config), "--out", str(run))
    last = err.strip().splitlines()[-1]
    assert code == 1 and "so far failed the same way, at iteration 1: diverged: initial residual" in last
    assert last.endswith(f"resume with: jaxsimrl train-foam --resume {run}")
    first = EpisodeLog.load(run / "episodes.csv", 10**6).rows
    assert 2 <= len(first) < 40 and {r["update"] for r in first} == {1}
    code, _, err = run_cli(capsys, "--resume", str(run))
    assert code == 1 and "failed the same way" in err.strip().splitlines()[-1]
    again = EpisodeLog.load(run / "episodes.csv", 10**6).rows
    assert again[:len(first)] == first and {r["update"] for r in again[len(first):]} == {2}


def test_the_iterations_plot_marks_failures_and_leaves_them_out_of_the_mean(tmp_path: Path) -> None:
    from matplotlib.figure import Figure

    from jaxsimrl.apps.foam import FAILED_OUTCOMES
    from jaxsimrl.apps.foam.episodes import EpisodeLog
    from jaxsimrl.evaluation.curves import plot_episode_iterations, read_episode_iterations

    outcomes = [("converged", 400), ("crashed", 1), ("converged", 600), ("diverged", 37), ("truncated", 800)]
    log = EpisodeLog(tmp_path / "episodes.csv")
    for env, (outcome, iterations) in enumerate(outcomes):
        log.add(env, 1, {"episode": {"outcome": outcome, "iterations": iterations, "actions": [[0.5, 0.5]]}})
    log.flush()
    episodes = read_episode_iterations(tmp_path / "episodes.csv", FAILED_OUTCOMES)
    ax = Figure().subplots()
    plot_episode_iterations(ax, episodes, window=100)
    lines = {line.get_label(): line for line in ax.get_lines()}
    (failed,) = [line for label, line in lines.items() if label.startswith("failed")]
    assert failed.get_marker() == "x" and failed.get_color() == "tab:red"
    assert list(failed.get_xdata()) == [2, 4] and list(failed.get_ydata()) == [1, 37]
    (mean,) = [line for label, line in lines.items() if "mean" in label]
    assert list(mean.get_xdata()) == [1, 3, 5]
    assert mean.get_ydata()[-1] == pytest.approx((400 + 600 + 800) / 3)
