"""Looking at a run without a notebook: `jaxsimrl plot RUN_DIR` and train-lorenz --tensorboard."""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from test_cli_lorenz import TINY_FLAGS, run_cli

from jaxsimrl.cli.main import main
from jaxsimrl.evaluation.curves import episode_curve

_TINY_RUN: list[Path] = []


def tiny_run(tmp_path_factory) -> Path:
    """One tiny train-lorenz run with --tensorboard for the whole session (test_introspect reads it too)."""
    if not _TINY_RUN:
        path = tmp_path_factory.mktemp("tiny") / "run"
        assert main(["train-lorenz", *TINY_FLAGS, "--tensorboard", "--out", str(path)]) == 0
        _TINY_RUN.append(path)
    return _TINY_RUN[0]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return tiny_run(tmp_path_factory)


def rows_of(run):
    return [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]


def read_scalars(directory):
    """{tag: [(step, value), ...]} from tensorboardX event files (TFRecord framing, Event protos)."""
    from tensorboardX.proto import event_pb2

    scalars = {}
    for path in sorted(directory.glob("events.out.tfevents.*")):
        data, i = path.read_bytes(), 0
        while i < len(data):
            (length,) = struct.unpack("<Q", data[i:i + 8])
            event = event_pb2.Event.FromString(data[i + 12:i + 12 + length])
            i += 12 + length + 4  # length, its crc, the record, its crc
            for value in event.summary.value:
                scalars.setdefault(value.tag, []).append((event.step, value.simple_value))
    return scalars


def test_plot_writes_the_training_curves(run, capsys):
    code, out, _ = run_cli(["plot", str(run)], capsys)
    assert code == 0 and str(run / "training_curves.png") in out
    with Image.open(run / "training_curves.png") as image:
        assert image.format == "PNG" and image.size[0] > 4 * image.size[1] > 1000  # a row of panels
    other = run.parent / "curves.png"
    assert run_cli(["plot", str(run), "--out", str(other)], capsys)[0] == 0 and other.is_file()


def test_foam_runs_get_an_iterations_panel(run, tmp_path, capsys):
    base = tmp_path / "base.png"
    assert run_cli(["plot", str(run), "--out", str(base)], capsys)[0] == 0
    (run / "episodes.csv").write_text("episode,iterations\n1,700\n2,650\n3,480\n")
    try:
        assert run_cli(["plot", str(run), "--out", str(tmp_path / "foam.png")], capsys)[0] == 0
    finally:
        (run / "episodes.csv").unlink()
    with Image.open(base) as plain, Image.open(tmp_path / "foam.png") as foam:
        assert foam.size[0] > plain.size[0] * 1.2  # one more panel
        assert foam.size[1] == plain.size[1]


def test_five_episode_moving_average():
    rows = [{"update": 1, "env_steps": 10, "episodes": 2, "mean_episode_return": 1.0},
            {"update": 2, "env_steps": 20, "episodes": 0, "mean_episode_return": math.nan},
            {"update": 3, "env_steps": 30, "episodes": 4, "mean_episode_return": 7.0}]
    curve = episode_curve(rows, window=5)
    np.testing.assert_array_equal(curve.episode, [1, 2, 3, 4, 5, 6])
    np.testing.assert_array_equal(curve.env_steps, [10, 10, 30, 30, 30, 30])
    np.testing.assert_allclose(curve.moving_average, [1, 1, 3, 4, 4.6, 5.8])  # last: (1 + 4 x 7) / 5


@pytest.mark.parametrize(("target", "expected"), [
    ("{tmp}/missing", "does not exist"),
    ("{tmp}/empty", "no metrics rows"),
    ("{tmp}/file.txt", "not a directory"),
])
def test_bad_run_directory_is_one_line_and_exit_2(tmp_path, capsys, target, expected):
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "config.json").write_text("{}")
    (tmp_path / "file.txt").write_text("x")
    code, _, err = run_cli(["plot", target.format(tmp=tmp_path)], capsys)
    assert code == 2 and expected in err and len(err.strip().splitlines()) == 1


def test_bad_out_is_one_line_and_exit_2(run, tmp_path, capsys):
    for out, expected in ((tmp_path / "no" / "such.png", "does not exist"), (tmp_path / "x.pdf", ".png")):
        code, _, err = run_cli(["plot", str(run), "--out", str(out)], capsys)
        assert code == 2 and expected in err and len(err.strip().splitlines()) == 1


def test_tensorboard_has_every_metric_at_its_env_steps(run):
    scalars = read_scalars(run / "tensorboard")
    rows = rows_of(run)
    steps = [row["env_steps"] for row in rows]
    for name in ("policy_loss", "value_loss", "entropy", "approx_kl", "learning_rate", "steps_per_s"):
        logged = scalars[f"train/{name}"]
        assert [step for step, _ in logged] == steps
        np.testing.assert_allclose([value for _, value in logged], [row[name] for row in rows], rtol=1e-6)
    # only updates in which an episode ended have a return (none do in this tiny run: NaN is skipped)
    returns = scalars.get("train/mean_episode_return", [])
    assert [step for step, _ in returns] == [row["env_steps"] for row in rows if row["episodes"] > 0]



def test_failed_episodes_are_those_the_run_s_application_calls_failed(tmp_path):
    """The iterations panel's failures: the outcomes the App of config.json's env names (none otherwise)."""
    from foam_bridge import FAILURES
    from jaxsimrl.cli.plot import _failed_outcomes

    (tmp_path / "config.json").write_text('{"env": "foam"}')
    assert _failed_outcomes(tmp_path) == frozenset(FAILURES)
    (tmp_path / "config.json").write_text('{"env": "lorenz"}')
    assert _failed_outcomes(tmp_path) == frozenset()  # the core's own env: no application
    (tmp_path / "config.json").write_text("not json")
    assert _failed_outcomes(tmp_path) == frozenset()
