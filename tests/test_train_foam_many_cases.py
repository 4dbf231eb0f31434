"""train-foam --family: one controller trained on many cases (jaxsimrl.apps.foam.cli.train_family), each in
its own box and criterion, its reward scaled by its own settings' iterations; resumed; then ``solve`` with it
on a case of the other algorithm. Real simpleFoam on coarse variants (``jaxsimrl family``) of two
tutorials."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from foam_marks import needs_openfoam
from test_train_foam_family import _cli

from jaxsimrl.apps.foam.solve import solve_case
from jaxsimrl.cli.main import main

TUTORIALS = Path("/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam")
TINY = ["--pool", "2", "--num-envs", "2", "--steps-per-update", "8", "--residual-features", "2",
        "--observe-progress", "--observe-action"]


def test_family_refuses_what_does_not_go_with_it(capsys, tmp_path: Path) -> None:
    code, err = _cli(capsys, "train-foam", "--family", tmp_path / "none", "--print-config")
    assert code == 2 and err.count("\n") == 1 and "not a directory" in err
    code, err = _cli(capsys, "train-foam", "--family", tmp_path, "--print-config")
    assert code == 2 and err.count("\n") == 1 and "no case" in err
    code, err = _cli(capsys, "train-foam", "--family", tmp_path, "--case", tmp_path, "--print-config")
    assert code == 2 and err.count("\n") == 1 and "--case does not go with --family" in err


@needs_openfoam
@pytest.mark.slow  # a family built, its own runs measured, two short trainings and a solve (~2 min)
def test_a_controller_trained_on_a_family_acts_in_each_case_s_box_and_solves_the_other_algorithm(
        capsys, tmp_path: Path) -> None:
    if not TUTORIALS.is_dir():
        pytest.skip("openfoam-examples not installed")
    family = tmp_path / "family"
    assert main(["family", str(TUTORIALS / "pitzDaily"), str(TUTORIALS / "pitzDailyExptInlet"), "--out",
                 str(family), "--variants", "1", "--seed", "0", "--mesh", "0.5", "0.5"]) == 0
    run = tmp_path / "run"
    code, err = _cli(capsys, "train-foam", "--family", family, *TINY, "--episodes", "2", "--out", run)
    assert code == 0, err
    config = json.loads((run / "config.json").read_text())
    cases = config["family"]
    assert set(cases) == {"pitzDaily-0", "pitzDailyExptInlet-0"}
    assert {cases[n]["simple_variant"] for n in cases} == {"SIMPLE", "SIMPLEC"}
    for name, case in cases.items():  # each its own box; a reward that counts its own iterations as 100
        assert case["action_share"] and not case["observe_state"] and case["observe_algorithm"]
        assert f"{name}: " in err and 0.05 < case["reward_scale"] < 1.0
    plain = cases["pitzDailyExptInlet-0"]  # plain SIMPLE: a box around its own factors (0.7, 0.3)
    assert plain["action_high"][1] == pytest.approx(0.375)
    rows = list(csv.DictReader((run / "episodes.csv").open()))
    assert rows and {row["case"] for row in rows} <= set(cases)
    for row in rows:  # the factors the solver got lie in that case's box
        low, high = cases[row["case"]]["action_low"], cases[row["case"]]["action_high"]
        for action in json.loads(row["actions"]):
            assert all(lo - 1e-6 <= a <= hi + 1e-6 for a, lo, hi in zip(action, low, high, strict=True))
    code, err = _cli(capsys, "train-foam", "--resume", run, "--episodes", str(len(rows) + 1))
    assert code == 0, err
    assert json.loads((run / "config.json").read_text())["family"] == cases  # not measured again
    assert "own settings" not in err
    # solve with it: no --family flag needed, the case's algorithm is observed, its box is its own
    for name in cases:
        out = tmp_path / f"solved-{name}"
        report = solve_case(family / name, out, policy=run, step_timeout_s=120)
        data = json.loads((out / "solve.json").read_text())
        assert "does not apply" not in data["result"]["fields_from"]  # both algorithms are its
        assert report.iterations > 0 and data["steps"][0]["source"] == "controller"
        low, high = data["settings"]["action_low"], data["settings"]["action_high"]
        for step in data["steps"]:
            assert all(lo - 1e-6 <= a <= hi + 1e-6 for a, lo, hi in zip(step["action"], low, high,
                                                                         strict=True))
