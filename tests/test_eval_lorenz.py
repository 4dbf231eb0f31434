"""eval-lorenz on a tiny trained run: eval.json contents, the uncontrolled baseline's physics, the PNG,
and determinism for a given seed."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image
from test_cli_lorenz import TINY_FLAGS

from jaxsimrl.cli.main import main
from jaxsimrl.envs.lorenz import P_MINUS

EPISODES = 6


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    run = tmp_path_factory.mktemp("eval") / "run"
    assert main(["train-lorenz", *TINY_FLAGS, "--out", str(run)]) == 0
    return run


@pytest.fixture(scope="module")
def evaluated(trained):
    assert main(["eval-lorenz", str(trained), "--episodes", str(EPISODES), "--seed", "5"]) == 0
    return json.loads((trained / "eval.json").read_text())


def test_eval_json_has_agent_and_baseline_statistics(evaluated, trained):
    for key in ("mean_return", "std_return", "min_return", "max_return", "fraction_above_threshold"):
        assert np.isfinite(evaluated[key]) and np.isfinite(evaluated["uncontrolled"][key])
    assert evaluated["episodes"] == EPISODES and evaluated["seed"] == 5 and evaluated["stochastic"] is False
    assert evaluated["checkpoint_update"] == 5 and evaluated["episode_steps"] == 4000
    for stats in (evaluated, evaluated["uncontrolled"]):
        assert stats["min_return"] <= stats["mean_return"] <= stats["max_return"]
        # returns are sums of 4000 rewards of +-10 (plus at most one -100 penalty)
        assert stats["min_return"] >= -40_100 and stats["max_return"] <= 40_000
        assert 0.0 <= stats["fraction_above_threshold"] <= 1.0


def test_uncontrolled_system_decays_to_the_fixed_point(evaluated):
    baseline = evaluated["uncontrolled"]
    # rho = 20 is only transiently chaotic: most of every episode is spent slow, near P+ or P-.
    assert baseline["mean_return"] < -20_000
    assert baseline["fraction_above_threshold"] < 0.5
    paper = evaluated["paper_initial_state"]
    assert paper["xyz"] == [1.0, 12.0, 9.0]
    np.testing.assert_allclose(paper["uncontrolled"]["final_xyz"], P_MINUS, atol=0.05)


def test_trajectory_png_is_a_valid_image(evaluated, trained):
    with Image.open(trained / "eval_trajectory.png") as image:
        image.verify()
    with Image.open(trained / "eval_trajectory.png") as image:
        assert image.format == "PNG" and image.size[0] > 800 and image.size[1] > 400
        pixels = np.asarray(image.convert("RGB"), dtype=int)
    # the controlled trajectory is drawn in blue, the uncontrolled one in black
    blue = (pixels[..., 2] > 150) & (pixels[..., 0] < 100)
    black = pixels.sum(axis=-1) < 60
    assert blue.sum() > 1000 and black.sum() > 1000


@pytest.mark.slow  # two more evaluations
def test_same_seed_gives_same_numbers_and_another_seed_other_states(evaluated, trained):
    assert main(["eval-lorenz", str(trained), "--episodes", str(EPISODES), "--seed", "5"]) == 0
    again = json.loads((trained / "eval.json").read_text())
    assert again == evaluated
    argv = ["eval-lorenz", str(trained), "--episodes", str(EPISODES), "--seed", "6", "--stochastic"]
    assert main(argv) == 0
    other = json.loads((trained / "eval.json").read_text())
    assert other["seed"] == 6 and other["stochastic"] is True
    assert other["uncontrolled"]["mean_return"] != evaluated["uncontrolled"]["mean_return"]
