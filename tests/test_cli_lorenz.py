"""train-lorenz from the command line: one-line errors with exit code 2, --help, and the contents of a
real (tiny) run directory."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from jaxsimrl.agents.ppo import PPOConfig
from jaxsimrl.cli.lorenz import KNOBS, _fresh_plan
from jaxsimrl.cli.main import build_parser, main

# A tiny but complete training run: 2 envs x 32 steps per update, 5 updates in chunks of 2.
TINY = ["--network", "mlp", "--num-envs", "2", "--steps-per-update", "64", "--seq-len", "16",
        "--num-minibatches", "2", "--total-steps", "320", "--updates-per-chunk", "2"]
TINY_FILE = {"lr": 1e-3, "gamma": 0.9, "ent_coef": 0.01}  # --config of the run below, whose --gamma wins
# The same resolved config from flags alone: the other test modules use it, so that every tiny run in
# one pytest process shares one trainer and compiles it once (training.lorenz.lorenz_trainer is cached).
TINY_FLAGS = [*TINY, "--lr", "1e-3", "--gamma", "0.95", "--ent-coef", "0.01"]


def run_cli(argv, capsys):
    """(exit code, stdout, stderr) of ``jaxsimrl argv`` run in-process."""
    try:
        code = main(argv)
    except SystemExit as exit_:  # argparse errors exit from inside the parser
        code = exit_.code
    out, err = capsys.readouterr()
    return code, out, err


def write_json(path: Path, obj) -> Path:
    path.write_text(obj if isinstance(obj, str) else json.dumps(obj))
    return path


def run_dir_without_checkpoint(tmp_path: Path) -> Path:
    run = tmp_path / "stopped"
    run.mkdir()
    write_json(run / "config.json", {"env": "lorenz", "seed": 0, "ppo": PPOConfig().to_dict()})
    return run


BAD_INPUTS = {
    "negative steps": (["train-lorenz", "--total-steps", "-5"], "--total-steps"),
    "fractional steps": (["train-lorenz", "--total-steps", "2.5"], "--total-steps"),
    "negative lr": (["train-lorenz", "--lr", "-1"], "--lr"),
    "negative seed": (["train-lorenz", "--seed", "-1"], "--seed"),
    "unknown network": (["train-lorenz", "--network", "gru"], "--network"),
    "envs not dividing steps": (["train-lorenz", "--num-envs", "3", "--steps-per-update", "64"], "divisible"),
    "gamma above one": (["train-lorenz", "--gamma", "2"], "gamma"),
    "seq_len not dividing": (["train-lorenz", "--seq-len", "7"], "seq_len"),
    "missing config": (["train-lorenz", "--config", "{tmp}/nope.json"], "nope.json"),
    "malformed config": (["train-lorenz", "--config", "{tmp}/bad.json"], "not valid JSON"),
    "binary config": (["train-lorenz", "--config", "{tmp}/binary.json"], "not valid JSON"),
    "config not an object": (["train-lorenz", "--config", "{tmp}/list.json"], "JSON object"),
    "unknown config key": (["train-lorenz", "--config", "{tmp}/unknown.json"], "learning_rate"),
    "config value of wrong type": (["train-lorenz", "--config", "{tmp}/wrongtype.json"], "num_envs"),
    "out is a non-empty dir": (["train-lorenz", "--out", "{tmp}/busy"], "--resume"),
    "out cannot be created": (["train-lorenz", "--out", "{tmp}/list.json/run"], "cannot create"),
    "resume a file": (["train-lorenz", "--resume", "{tmp}/list.json"], "not a directory"),
    "resume missing dir": (["train-lorenz", "--resume", "{tmp}/missing"], "does not exist"),
    "resume dir without checkpoint": (["train-lorenz", "--resume", "{tmp}/stopped"], "no checkpoint"),
    "resume with a non-integer seed": (["train-lorenz", "--resume", "{tmp}/badseed"], "seed must be an int"),
    "resume with a config flag": (["train-lorenz", "--resume", "{tmp}/stopped", "--lr", "1e-3"], "--lr"),
    "resume with a network flag": (["train-lorenz", "--resume", "{tmp}/stopped", "--network", "mlp"],
                                   "--network"),
    "unknown flag": (["train-lorenz", "--learning-rate", "1"], "--learning-rate"),
    "eval missing dir": (["eval-lorenz", "{tmp}/missing"], "does not exist"),
    "eval without checkpoint": (["eval-lorenz", "{tmp}/stopped"], "no checkpoint"),
    "eval zero episodes": (["eval-lorenz", "{tmp}/stopped", "--episodes", "0"], "--episodes"),
}


@pytest.mark.parametrize("case", BAD_INPUTS)
def test_bad_input_is_one_line_on_stderr_and_exit_2(case, tmp_path, capsys):
    write_json(tmp_path / "bad.json", "{num_envs: 2")
    write_json(tmp_path / "list.json", [1, 2])
    (tmp_path / "binary.json").write_bytes(b"\x80\x81{")
    write_json(tmp_path / "unknown.json", {"learning_rate": 1e-3})
    write_json(tmp_path / "wrongtype.json", {"num_envs": "two"})
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "metrics.jsonl").write_text("{}\n")
    run_dir_without_checkpoint(tmp_path)
    (tmp_path / "badseed").mkdir()
    write_json(tmp_path / "badseed" / "config.json", {"seed": "0", "ppo": PPOConfig().to_dict()})
    argv, needle = BAD_INPUTS[case]
    code, out, err = run_cli([arg.format(tmp=tmp_path) for arg in argv], capsys)
    assert code == 2
    assert len(err.strip().splitlines()) == 1, err
    assert "Traceback" not in err and needle in err
    assert err.startswith("jaxsimrl") and ": error: " in err
    assert not (tmp_path / "runs").exists()  # nothing created for a rejected command


def test_console_script_reports_bad_flag_in_one_line(tmp_path):
    script = Path(sys.executable).with_name("jaxsimrl")
    result = subprocess.run([str(script), "train-lorenz", "--num-envs", "3", "--steps-per-update", "64",
                             "--out", str(tmp_path / "run")], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "divisible by num_envs" in result.stderr
    assert not (tmp_path / "run").exists()


def test_help_documents_every_flag(capsys):
    code, out, _ = run_cli(["train-lorenz", "--help"], capsys)
    assert code == 0
    flags = ["--" + name.replace("_", "-") for name, _, _ in KNOBS]
    for flag in [*flags, "--network", "--seed", "--out", "--config", "--resume", "--print-config"]:
        assert flag in out
    code, out, _ = run_cli(["eval-lorenz", "--help"], capsys)
    assert code == 0 and all(flag in out for flag in ("--episodes", "--stochastic", "--seed", "RUN_DIR"))


def test_print_config_shows_every_resolved_field_without_training(tmp_path, capsys):
    config = write_json(tmp_path / "cfg.json", {"gamma": 0.9, "seq_len": 100})
    code, out, _ = run_cli(["train-lorenz", "--print-config", "--config", str(config), "--gamma", "0.97",
                            "--out", str(tmp_path / "run")], capsys)
    printed = json.loads(out)
    assert code == 0 and printed == {**PPOConfig().to_dict(), "gamma": 0.97, "seq_len": 100}
    assert not (tmp_path / "run").exists()


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """A finished tiny run; --config sets lr and gamma, the --gamma flag overrides the file."""
    root = tmp_path_factory.mktemp("cli")
    config = write_json(root / "cfg.json", TINY_FILE)
    out = root / "run"
    try:
        code = main(["train-lorenz", *TINY, "--config", str(config), "--gamma", "0.95", "--seed", "7",
                     "--out", str(out)])
    except SystemExit as exit_:
        code = exit_.code
    assert code == 0
    return out


def test_run_dir_holds_config_metrics_summary_and_two_checkpoints(tiny_run):
    names = {p.name for p in tiny_run.iterdir()}
    assert {"config.json", "metrics.jsonl", "metrics.csv", "summary.json", "checkpoints"} <= names
    rows = [json.loads(line) for line in (tiny_run / "metrics.jsonl").read_text().splitlines()]
    assert [row["update"] for row in rows] == [1, 2, 3, 4, 5]  # total 320 / 64 per update
    assert [row["env_steps"] for row in rows] == [64, 128, 192, 256, 320]
    for key in ("wall_time_s", "steps_per_s", "mean_episode_return", "policy_loss", "value_loss", "entropy"):
        assert key in rows[0]
    assert len((tiny_run / "metrics.csv").read_text().splitlines()) == 1 + len(rows)
    # chunks of 2 updates end at updates 2, 4, 5; the last two are kept
    assert sorted(int(p.name) for p in (tiny_run / "checkpoints").iterdir()) == [4, 5]
    summary = json.loads((tiny_run / "summary.json").read_text())
    assert summary["total_steps"] == 320 and summary["updates"] == 5 and summary["complete"] is True
    assert summary["wall_time_s"] > 0
    assert summary["steps_per_s"] == pytest.approx(320 / summary["wall_time_s"])
    assert "final_mean_return" in summary  # null here: no 4000-step episode ends in 160 steps per env


def test_config_json_round_trips_with_flags_over_file_over_defaults(tiny_run):
    record = json.loads((tiny_run / "config.json").read_text())
    config = PPOConfig.from_dict(record["ppo"])
    assert config.lr == 1e-3 and config.ent_coef == 0.01  # from the file
    assert config.gamma == 0.95 and config.network == "mlp"  # flags beat the file
    assert config.clip_eps == PPOConfig().clip_eps  # untouched default
    assert record["seed"] == 7 and record["env"] == "lorenz"
    assert record["jax_version"] and record["devices"]


def test_flags_alone_resolve_to_the_same_config_as_file_plus_flag(tiny_run):
    args = build_parser().parse_args(["train-lorenz", *TINY_FLAGS])
    record = json.loads((tiny_run / "config.json").read_text())
    assert _fresh_plan(args).config == PPOConfig.from_dict(record["ppo"])


def test_closing_summary_and_rerun_into_same_out_is_refused(tiny_run, capsys):
    code, out, err = run_cli(["train-lorenz", *TINY, "--out", str(tiny_run)], capsys)
    assert code == 2 and f"--resume {tiny_run}" in err
    code, out, err = run_cli(["train-lorenz", "--resume", str(tiny_run), "--total-steps", "256"], capsys)
    assert code == 2 and "may only be raised" in err and len(err.splitlines()) == 1
    code, out, err = run_cli(["train-lorenz", "--resume", str(tiny_run)], capsys)
    assert code == 0 and "done: 5 updates, 320 env steps" in out and "eval-lorenz" in out


@pytest.mark.slow  # trains twice
def test_resuming_a_finished_annealed_run_with_more_steps_trains_at_a_nonzero_rate(tmp_path, capsys):
    run = tmp_path / "annealed"
    config = write_json(tmp_path / "anneal.json", {"anneal_lr": True})
    assert main(["train-lorenz", *TINY_FLAGS, "--config", str(config), "--out", str(run)]) == 0
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert rows[-1]["learning_rate"] < rows[0]["learning_rate"]  # it decayed towards 0 at update 5
    capsys.readouterr()
    code, _, err = run_cli(["train-lorenz", "--resume", str(run), "--total-steps", "640"], capsys)
    assert code == 0
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert [row["update"] for row in rows] == list(range(1, 11))
    later = [row["learning_rate"] for row in rows[5:]]
    # the extension learns: the rate of a run planned for 10 updates, decaying from lr / 2
    assert later[0] == pytest.approx(1e-3 * 5 / 10, rel=1e-4) and later == sorted(later, reverse=True)
    assert later[-1] > 0 and "decays to 0 at update 10" in err  # and it says so
