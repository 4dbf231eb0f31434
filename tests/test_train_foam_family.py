"""train-foam, grid-foam and eval-foam with what issue 18 section 1 adds: the k/omega factor as a third
action, the closed-loop observation and a family of step heights (real simpleFoam, mesh 0.4); and the
2-action runs and grids of before, which keep loading as they were."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest
from foam_marks import needs_openfoam

from foam_bridge._config import STEP_HEIGHT_H, FoamEnvConfig
from foam_bridge._grid import read_grid_csv
from jaxsimrl.apps.foam.config import foam_config_from_json
from jaxsimrl.apps.foam.episodes import EpisodeLog
from jaxsimrl.cli.main import main

REPO = Path(__file__).resolve().parents[1]
H, H2 = STEP_HEIGHT_H, 2 * STEP_HEIGHT_H
TINY = ["--mesh-scale", "0.4", "--pool", "2", "--steps-per-update", "8", "--max-iterations", "600"]
OBSERVE = {"foam": {"residual_features": 1, "observe_progress": True, "observe_action": True,
                    "scale_free_state": True}}
NEW_FIELDS = ("observe_progress", "observe_action", "scale_free_state")


def _cli(capsys, *argv: str) -> tuple[int, str]:
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exit_:
        code = exit_.code
    return code, capsys.readouterr().err


def test_the_runs_and_grids_of_before_load_as_they_were():
    for path in sorted((REPO / "experiments" / "foam").glob("*/config.json"))[:5]:
        foam = json.loads(path.read_text())["foam"]
        assert not set(NEW_FIELDS) & set(foam)
        cfg = foam_config_from_json(foam)
        assert cfg.action_size == 2 and cfg.height_range is None and len(cfg.action_low) == 2
        assert cfg.observation_size == 1 + cfg.residual_features * len(cfg.convergence)
    cells = read_grid_csv(next((REPO / "experiments" / "foam" / "constant_factors").glob("*/grid.csv")))
    assert cells and all(cell.alpha_t is None and len(cell.factors) == 2 for cell in cells)


def test_train_foam_flags_and_their_errors(capsys, tmp_path):
    assert main(["train-foam", "--print-config", "--relax-k-omega", "action", "--step-height", str(H),
                 str(H2)]) == 0
    foam = json.loads(capsys.readouterr().out)["foam"]
    assert foam["relax_k_omega"] == "action" and foam["action_low"] == [0.2] * 3
    assert foam["action_high"] == [0.95] * 3 and foam["step_height"] == [H, H2]
    assert main(["train-foam", "--print-config"]) == 0  # today's defaults, unchanged
    foam = json.loads(capsys.readouterr().out)["foam"]
    assert foam["relax_k_omega"] == 0.8 and foam["step_height"] == H and foam["action_low"] == [0.2, 0.2]
    assert not any(foam[name] for name in NEW_FIELDS)
    assert main(["train-foam", "--print-config", "--residual-features", "2", *(f"--{n.replace('_', '-')}"
                                                                              for n in NEW_FIELDS)]) == 0
    foam = json.loads(capsys.readouterr().out)["foam"]
    assert foam["residual_features"] == 2 and all(foam[name] is True for name in NEW_FIELDS)
    code, err = _cli(capsys, "train-foam", "--resume", str(tmp_path), "--observe-action")
    assert code == 2 and "--observe-action cannot be used with --resume" in err
    for argv, message in [(["--step-height", str(H2), str(H)], "LOW <= HIGH"),
                          (["--step-height", "1", "2", "3"], "one height or LOW HIGH"),
                          (["--relax-k-omega", "sometimes"], "relaxation factor"),
                          (["--case", str(tmp_path), "--step-height", str(H), str(H2)], "built-in")]:
        (tmp_path / "system").mkdir(exist_ok=True)
        code, err = _cli(capsys, "train-foam", "--print-config", *argv)
        assert code == 2 and message in err and len(err.strip().splitlines()) <= 2, (argv, err)


@pytest.fixture(scope="module")
def family_run(tmp_path_factory) -> Path:
    """A tiny train-foam run with the three features together."""
    root = tmp_path_factory.mktemp("family")
    config = root / "observe.json"
    config.write_text(json.dumps(OBSERVE))
    run = root / "run"
    assert main(["train-foam", *TINY, "--episodes", "4", "--seed", "3", "--relax-k-omega", "action",
                 "--step-height", str(H), str(H2), "--config", str(config), "--out", str(run)]) == 0
    return run


@pytest.mark.slow  # family_run: a real train-foam run
@needs_openfoam
def test_train_foam_with_all_three_features(family_run):
    foam = json.loads((family_run / "config.json").read_text())["foam"]
    cfg = foam_config_from_json(foam)
    assert cfg.action_size == 3 and cfg.observation_size == 1 + 4 + 1 + 3 and cfg.height_range == (H, H2)
    rows = EpisodeLog.load(family_run / "episodes.csv", 10**6).rows
    assert len(rows) >= 4
    heights = [row["step_height"] for row in rows]
    assert all(H <= h <= H2 for h in heights) and len(set(heights)) == len(heights)
    assert all(len(action) == 3 for row in rows for action in row["actions"])
    header = (family_run / "episodes.csv").read_text().splitlines()[0]
    assert header.endswith(",step_height,case")  # a one-case run leaves the family column empty
    assert all(row["case"] == "" for row in rows)


@pytest.mark.slow  # family_run: a real train-foam run
@needs_openfoam
def test_init_from_refuses_a_policy_with_another_number_of_factors(family_run, tmp_path, capsys):
    # 1 + 2 x 4 residual features: the family run's observation size (9), with 2 factors instead of 3
    code, err = _cli(capsys, "train-foam", *TINY, "--residual-features", "2", "--init-from", family_run,
                     "--out", tmp_path / "two")
    assert code == 2 and "acts in the box" in err and not (tmp_path / "two").exists()


@pytest.mark.slow  # family_run, a grid and an eval-foam run
@needs_openfoam
def test_grid_foam_3d_and_eval_foam_of_a_3_action_policy(family_run, tmp_path, capsys):
    grid = tmp_path / "grid"
    assert main(["grid-foam", "--alpha-u", "0.95", "--alpha-p", "0.875", "--alpha-t", "0.5", "0.8",
                 "--mesh-scale", "0.4", "--max-iterations", "600", "--inlet-velocity", "50", "--pool", "2",
                 "--out", str(grid)]) == 0
    with open(grid / "grid.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [(r["alpha_t"], r["outcome"]) for r in rows] == [("0.5", "converged"), ("0.8", "converged")]
    assert rows[0]["iterations"] != rows[1]["iterations"]  # alpha_t reaches the solver
    assert sorted(p.name for p in grid.glob("*.png")) == ["grid_alpha_t_0.5.png", "grid_alpha_t_0.8.png"]
    best = min(rows, key=lambda r: int(r["iterations"]))
    out = tmp_path / "eval"
    assert main(["eval-foam", str(family_run), "--velocities", "50", "--step-height", str(1.5 * H),
                 "--mesh-scale", "0.4", "--samples", "1", "--pool", "2", "--baseline-grid",
                 str(grid / "grid.csv"), "--controllers", "learned_deterministic", "best_constant",
                 "tutorial_defaults", "--out", str(out)]) == 0
    report = json.loads((out / "eval.json").read_text())
    assert report["baseline"]["alpha_t"] == float(best["alpha_t"])
    assert set(report["results"]) == {"learned_deterministic", "best_constant", "tutorial_defaults"}
    assert report["action_box"]["low"] == [0.2] * 3 and (out / "factors.png").is_file()  # a row per factor
    with open(out / "eval.csv", newline="") as handle:
        runs = list(csv.DictReader(handle))
    assert {r["geometry"] for r in runs} == {"1.5h"} and all(r["outcome"] for r in runs)
    assert math.isclose(float(runs[0]["step_height"]), 1.5 * H)


def test_a_3d_grid_best_cell_is_refused_for_a_2_action_policy(tmp_path):
    from jaxsimrl.apps.foam.evaluation.baseline import as_action

    two = FoamEnvConfig().validate()
    assert as_action(two, (0.9, 0.8)) == (0.9, 0.8)
    assert as_action(FoamEnvConfig(relax_k_omega="action").validate(), (0.9, 0.8)) == (0.9, 0.8, 0.8)
    with pytest.raises(ValueError, match="--relax-k-omega action"):
        as_action(two, (0.9, 0.8, 0.5))
