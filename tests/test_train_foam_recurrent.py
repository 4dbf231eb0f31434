"""A recurrent controller trained on generated cases (issue 47): train-foam --family over a directory that
foam_bridge's generator made takes each case's own run from the generator's manifest (nothing measured
again), scales a solver-time reward by the own run's CPU seconds, trains an LSTM that observes the last
step's gain and whose share 0.5 is each case's own factors, resumes, and ``solve`` runs it on a case
with its recurrent state and the same pivot. Real simpleFoam on coarse generated cases."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from foam_marks import needs_openfoam
from test_train_foam_family import _cli

from foam_bridge import generate_cases
from jaxsimrl.apps.foam.cli.train_family import family_case_dirs
from jaxsimrl.apps.foam.solve import solve_case

RECURRENT = {"ppo": {"network": "lstm", "hidden_sizes": [16], "lstm_size": 16, "seq_len": 4,
                     "num_minibatches": 1, "update_epochs": 1},
             "foam": {"interval": 25, "pivot_at": "own", "action_radius": 0.15}}
TINY = ["--pool", "2", "--num-envs", "2", "--steps-per-update", "8", "--residual-features", "2",
        "--observe-progress", "--observe-action", "--observe-gain", "--reward", "solver-time"]


def test_a_family_skips_hidden_directories(tmp_path: Path) -> None:
    for name in ("case", ".scratch"):
        (tmp_path / name / "system").mkdir(parents=True)
        (tmp_path / name / "system" / "controlDict").write_text("")
    assert [p.name for p in family_case_dirs([tmp_path])] == ["case"]


@needs_openfoam
@pytest.mark.slow  # two coarse cases generated, two short trainings and a solve (~1-2 min)
def test_a_recurrent_controller_trains_on_generated_cases_and_solves_with_its_state(
        capsys, tmp_path: Path) -> None:
    family = tmp_path / "generated"
    made = generate_cases(family, 2, seed=0, kinds=("contraction", "diffuser"), resolution=0.4, workers=2)
    assert {case.spec.algorithm for case in made} == {"SIMPLE", "SIMPLEC"}
    config = tmp_path / "recurrent.json"
    config.write_text(json.dumps(RECURRENT))
    run = tmp_path / "run"
    code, err = _cli(capsys, "train-foam", "--family", family, "--config", config, *TINY, "--episodes", "2",
                     "--out", run)
    assert code == 0, err
    written = json.loads((run / "config.json").read_text())
    assert written["ppo"]["network"] == "lstm"
    for case in made:  # the generator's own run, not a new one: its CPU seconds are the reward's unit
        entry = written["family"][case.name]
        assert f"{case.name}: " in err and "as the generator ran them" in err
        assert entry["reward_scale"] == pytest.approx(100.0 / max(case.cpu_s, 1e-3))
        assert entry["observe_gain"] and entry["reward"] == "solver-time"
        own = dict(case.spec.factors)
        assert entry["action_pivot"] == pytest.approx([own["U"], own["p"], own["turbulence"]])  # 0.5: own
    rows = list(csv.DictReader((run / "episodes.csv").open()))
    assert len(rows) >= 2 and all(row["outcome"] in ("converged", "truncated") for row in rows)
    code, err = _cli(capsys, "train-foam", "--resume", run, "--episodes", str(len(rows) + 1))
    assert code == 0, err
    case = made[0].path
    out = tmp_path / "solved"
    report = solve_case(case, out, policy=run, step_timeout_s=120)
    data = json.loads((out / "solve.json").read_text())
    assert report.iterations > 0 and data["steps"][0]["source"] == "controller"
    assert data["settings"]["action_pivot"] == pytest.approx(written["family"][made[0].name]["action_pivot"])
    assert data["settings"]["action_radius"] == 0.15  # the policy's action means what it meant in training
