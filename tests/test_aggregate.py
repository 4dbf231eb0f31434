"""Aggregate results across agents with rliable: the IQM is the 25 %-trimmed mean, its stratified-bootstrap
interval holds it and is reproducible with its seed, the performance profile is the fraction of agents
above each threshold, and eval-lorenz of a batch writes them (eval.json, printed, eval_profile.png)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.stats
from PIL import Image
from test_cli_lorenz import run_cli
from test_seed_batch import train_batch

from jaxsimrl.evaluation.aggregate import interval_estimates, performance_profile

# 16 "agents": most near 15,000, one collapsed and one outstanding (rliable's case for the IQM)
SCORES = [15789.0, 15418.0, 16942.0, 15573.0, 16498.0, 13517.0, -20000.0, 17299.0, 18000.0, 15000.0,
          14000.0, 16000.0, 16500.0, 15900.0, 39000.0, 12000.0]


def test_iqm_is_the_quarter_trimmed_mean_inside_its_interval():
    stats = interval_estimates(SCORES, reps=500)
    assert stats["count"] == 16 and stats["bootstrap"]["reps"] == 500
    assert stats["iqm"]["value"] == pytest.approx(scipy.stats.trim_mean(SCORES, 0.25))
    assert stats["median"]["value"] == pytest.approx(np.median(SCORES))
    assert stats["mean"]["value"] == pytest.approx(np.mean(SCORES))
    for name in ("iqm", "median", "mean"):
        assert stats[name]["ci_low"] <= stats[name]["value"] <= stats[name]["ci_high"], name
    # the IQM shrugs off the two outliers that widen the mean's interval
    width = {name: stats[name]["ci_high"] - stats[name]["ci_low"] for name in ("iqm", "mean")}
    assert width["iqm"] < width["mean"] / 2


def test_intervals_are_reproducible_with_their_seed_and_leave_numpy_alone():
    np.random.seed(123)
    before = np.random.get_state()[1].copy()
    first, again = interval_estimates(SCORES, reps=300, seed=7), interval_estimates(SCORES, reps=300, seed=7)
    other = interval_estimates(SCORES, reps=300, seed=8)
    assert first == again and first["iqm"] != other["iqm"]
    np.testing.assert_array_equal(np.random.get_state()[1], before)  # the caller's global state is back


def test_bad_scores_are_refused():
    for bad in ([], [1.0, float("nan")], [float("inf")]):
        with pytest.raises(ValueError, match="finite scores"):
            interval_estimates(bad)


def test_profile_is_the_fraction_of_agents_above_each_threshold():
    profile, band = performance_profile([1.0, 2.0, 3.0, 4.0], np.array([0.0, 1.5, 3.5, 5.0]), reps=200)
    np.testing.assert_allclose(profile, [1.0, 0.75, 0.25, 0.0])
    assert band.shape == (2, 4) and np.all(band[0] <= profile) and np.all(profile <= band[1])


@pytest.mark.slow  # trains and evaluates a batch
def test_eval_of_a_batch_reports_iqm_with_interval_and_draws_the_profile(tmp_path, capsys):
    batch = train_batch(tmp_path / "three", (0, 1, 2))
    code, out, _ = run_cli(["eval-lorenz", str(batch), "--episodes", "2"], capsys)
    report = json.loads((batch / "eval.json").read_text())
    means = [agent["mean_return"] for agent in report["agents"]]
    stats = report["aggregate"]
    assert code == 0 and stats["of"] == "mean_return" and stats["count"] == 3
    assert stats["iqm"]["value"] == pytest.approx(scipy.stats.trim_mean(means, 0.25))
    assert stats["iqm"]["ci_low"] <= stats["iqm"]["value"] <= stats["iqm"]["ci_high"]
    assert f"IQM {stats['iqm']['value']:.1f} [{stats['iqm']['ci_low']:.1f}" in out
    assert report["profile_plot"] == "eval_profile.png" and str(batch / "eval_profile.png") in out
    with Image.open(batch / "eval_profile.png") as image:
        assert image.format == "PNG" and image.size[0] > 300
    code, _, _ = run_cli(["eval-lorenz", str(batch), "--episodes", "2", "--agent", "0"], capsys)  # one agent
    assert code == 0 and "aggregate" not in json.loads((batch / "eval-agent-0.json").read_text())
