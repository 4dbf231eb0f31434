"""train-lorenz --seeds / --sweep: many agents in one jitted call. Agent i of a batch matches a --seed
run of its seed (and swept values) alone, up to float rounding; the run directory holds every agent, a
batch resumes exactly, eval-lorenz, load_policy and plot take the agents, and a batch too large for
memory is refused before it runs."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap
from pathlib import Path

import jax
import numpy as np
import pytest
from test_cli_lorenz import TINY_FLAGS, run_cli
from test_ppo_devices import two_devices_env
from test_resume import final_state, metrics, stop_after, train

from jaxsimrl.agents.ppo import batch as batch_module
from jaxsimrl.cli.lorenz import INTERRUPTED
from jaxsimrl.cli.main import main
from jaxsimrl.introspect import load_agents, load_policy
from jaxsimrl.runs.run_dir import summarise, summarise_agents

SEEDS = (0, 3)  # agent 1 is seed 3, the seed of test_resume's single runs
# Measured on a 2-core CPU (jax 0.10.2): a vmapped agent differs from its single-seed run by at most
# 2.4e-7 in any metric (losses of order 0.01-1) and 1.2e-7 in any parameter after 3 updates of 256 steps;
# the tolerances leave a margin of ~10x for other machines' reductions.
METRIC_RTOL, METRIC_ATOL = 1e-5, 2e-6
PARAM_ATOL = 2e-6
EXACT = ("update", "env_steps", "episodes", "learning_rate")


def by_agent(rows: list[dict], agent: int) -> list[dict]:
    return [{k: v for k, v in row.items() if k != "agent"} for row in rows if row["agent"] == agent]


def assert_rows_close(batch_rows: list[dict], single_rows: list[dict]) -> None:
    assert len(batch_rows) == len(single_rows) > 0 and batch_rows[0].keys() == single_rows[0].keys()
    for got, want in zip(batch_rows, single_rows, strict=True):
        for name, value in want.items():
            if name in EXACT:
                assert got[name] == value, name
            elif value is not None:
                assert got[name] == pytest.approx(value, rel=METRIC_RTOL, abs=METRIC_ATOL), name


def train_batch(out: Path, seeds: tuple[int, ...] = SEEDS) -> Path:
    """A finished tiny --seeds batch of ``seeds`` in ``out`` (shared with other test modules)."""
    assert main(["train-lorenz", *TINY_FLAGS, "--seeds", ",".join(map(str, seeds)), "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A finished --seeds 0,3 batch, and --seed 3 alone, on the same tiny config."""
    root = tmp_path_factory.mktemp("batch")
    batch, single = train_batch(root / "batch"), root / "single"
    assert main(["train-lorenz", *TINY_FLAGS, "--seed", str(SEEDS[1]), "--out", str(single)]) == 0
    return batch, single


@pytest.mark.slow  # runs: trains a batch and single seeds
def test_each_agent_of_a_batch_matches_its_seed_trained_alone(runs):
    batch, single = runs
    rows = metrics(batch)
    assert [row["agent"] for row in rows[:4]] == [0, 1, 0, 1]  # ordered by update, then agent
    assert_rows_close(by_agent(rows, 1), metrics(single))
    alone, agent = load_policy(single), load_policy(batch, agent=1)
    pairs = zip(jax.tree.leaves(alone.params), jax.tree.leaves(agent.params), strict=True)
    assert max(float(np.max(np.abs(np.asarray(a) - np.asarray(b)))) for a, b in pairs) <= PARAM_ATOL
    # and the agents are independent: seed 0's agent learns other numbers
    other = by_agent(rows, 0)
    assert not all(math.isclose(a["policy_loss"], b["policy_loss"], rel_tol=1e-3)
                   for a, b in zip(other, metrics(single), strict=True))


@pytest.mark.slow  # runs: trains
def test_run_dir_holds_every_agent(runs):
    batch, _ = runs
    record = json.loads((batch / "config.json").read_text())
    assert record["seeds"] == list(SEEDS) and "seed" not in record
    csv_lines = (batch / "metrics.csv").read_text().splitlines()
    assert csv_lines[0].startswith("update,agent,") and len(csv_lines) == 1 + 5 * len(SEEDS)
    summary = json.loads((batch / "summary.json").read_text())
    assert summary["num_agents"] == 2 and [a["seed"] for a in summary["agents"]] == list(SEEDS)
    assert summary["updates"] == 5 and summary["total_steps"] == 320 and summary["complete"]
    assert summary["all_agents_steps_per_s"] == pytest.approx(2 * summary["steps_per_s"])
    state, meta = final_state(batch)  # one orbax tree: every leaf has the agent axis in front
    assert meta["update"] == 5 and {leaf.shape[0] for leaf in jax.tree.leaves(state)} == {2}
    policies = load_agents(batch)
    assert [p.agent for p in policies] == [0, 1] and "agent 1" in repr(policies[1])


def test_summary_of_agents_is_each_agents_summary_and_their_mean():
    def rows(agent: int, returns: list[float | None]) -> list[dict]:
        return [{"update": u + 1, "agent": agent, "env_steps": 10 * (u + 1), "wall_time_s": u + 1.0,
                 "steps_per_s": 10.0, "mean_episode_return": math.nan if r is None else r,
                 "episodes": 0 if r is None else 2} for u, r in enumerate(returns)]

    a, b, c = rows(0, [1.0, 3.0]), rows(1, [5.0, None]), rows(2, [None, None])
    mixed = [row for trio in zip(a, b, c, strict=True) for row in trio]
    summary = summarise_agents(mixed, {"seeds": [4, 5, 6]})
    assert [agent["seed"] for agent in summary["agents"]] == [4, 5, 6]
    for agent, own in zip(summary["agents"], (a, b, c), strict=True):
        alone = summarise(own)
        for key in ("final_mean_return", "best_mean_return", "final_return_updates"):
            assert agent[key] == alone[key] or (math.isnan(agent[key]) and math.isnan(alone[key]))
    assert summary["final_mean_return"] == pytest.approx((2.0 + 5.0) / 2)  # agent 2 has no episode
    assert summary["final_mean_return_agents"]["count"] == 2
    assert summary["best_mean_return"] == pytest.approx((3.0 + 5.0) / 2)
    assert summary["total_steps"] == 20 and summary["updates"] == 2


@pytest.mark.slow  # runs: trains
def test_a_batch_resumes_to_exactly_the_uninterrupted_batch(runs, tmp_path, capsys):
    whole, _ = runs
    split = tmp_path / "split"
    seeds = ",".join(map(str, SEEDS))
    assert train([*TINY_FLAGS, "--seeds", seeds, "--out", str(split)], on_chunk=stop_after(2)) == INTERRUPTED
    assert f"--resume {split}" in capsys.readouterr().err
    # cut after update 3's rows were written but before its checkpoint, mid-line
    with (split / "metrics.jsonl").open("a") as handle:
        handle.write(json.dumps({"update": 3, "agent": 0, "env_steps": 192, "policy_loss": 1.0}) + "\n")
        handle.write('{"update": 3, "agent": 1, "env_ste')
    code, _, err = run_cli(["train-lorenz", "--resume", str(split), "--seeds", "0-1"], capsys)
    assert code == 2 and "--seeds cannot be used with --resume" in err
    assert main(["train-lorenz", "--resume", str(split)]) == 0
    assert metrics(split) == metrics(whole)
    states = (jax.tree.leaves(final_state(run)[0]) for run in (whole, split))
    for a, b in zip(*states, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.slow  # runs: trains; evaluates
def test_eval_takes_one_agent_or_all_of_them(runs, capsys):
    batch, single = runs
    code, out, _ = run_cli(["eval-lorenz", str(batch), "--episodes", "2"], capsys)
    assert code == 0 and "mean of 2 agents" in out
    every = json.loads((batch / "eval.json").read_text())
    assert every["num_agents"] == 2 and [a["agent_seed"] for a in every["agents"]] == list(SEEDS)
    means = [agent["mean_return"] for agent in every["agents"]]
    assert every["mean_return"] == pytest.approx(np.mean(means))
    code, out, _ = run_cli(["eval-lorenz", str(batch), "--episodes", "2", "--agent", "1"], capsys)
    one = json.loads((batch / "eval-agent-1.json").read_text())
    assert code == 0 and "agent 1 (seed 3)" in out and (batch / "eval_trajectory-agent-1.png").is_file()
    # the same initial states: the agent scores as it does within the batch's evaluation
    assert one["mean_return"] == pytest.approx(means[1], rel=1e-3)
    assert one["uncontrolled"] == every["uncontrolled"]
    for argv, needle in ((["eval-lorenz", str(batch), "--agent", "2"], "K in 0..1 (got 2)"),
                         (["eval-lorenz", str(single), "--agent", "0"], "holds one agent")):
        code, _, err = run_cli(argv, capsys)
        assert code == 2 and len(err.strip().splitlines()) == 1 and needle in err
    with pytest.raises(ValueError, match="holds 2 agents"):
        load_policy(batch)


@pytest.mark.slow  # runs: trains; and a sweep
def test_a_sweep_agent_matches_a_single_run_with_its_values(runs, tmp_path):
    _, single = runs  # seed 3, lr 1e-3
    at = TINY_FLAGS.index("--lr")
    flags = TINY_FLAGS[:at] + TINY_FLAGS[at + 2:]  # lr is swept
    sweep, slow = tmp_path / "sweep", tmp_path / "slow"
    assert main(["train-lorenz", *flags, "--sweep", "lr=1e-3,3e-4", "--seeds", "3", "--out", str(sweep)]) == 0
    assert main(["train-lorenz", *flags, "--lr", "3e-4", "--seed", "3", "--out", str(slow)]) == 0
    rows = metrics(sweep)
    assert_rows_close(by_agent(rows, 0), metrics(single))
    assert_rows_close(by_agent(rows, 1), metrics(slow))
    summary = json.loads((sweep / "summary.json").read_text())
    assert [(a["seed"], a["lr"]) for a in summary["agents"]] == [(3, 1e-3), (3, 3e-4)]
    assert load_policy(sweep, agent=1).config.lr == 3e-4


@pytest.mark.slow  # runs: trains
def test_plot_draws_a_batch(runs, capsys):
    batch, _ = runs
    code, out, _ = run_cli(["plot", str(batch), "--out", str(batch / "curves.png")], capsys)
    assert code == 0 and (batch / "curves.png").stat().st_size > 10_000


def test_tensorboard_gives_each_agent_its_own_curves(tmp_path):
    from test_cli_plot import read_scalars

    from jaxsimrl.runs.tensorboard import TensorBoardWriter

    writer = TensorBoardWriter(tmp_path)
    writer.write_rows([{"update": 1, "agent": k, "env_steps": 64, "entropy": 1.0 + k} for k in range(2)])
    writer.close()
    scalars = read_scalars(tmp_path)
    assert scalars == {"train/agent-0/update": [(64, 1.0)], "train/agent-0/entropy": [(64, 1.0)],
                       "train/agent-1/update": [(64, 1.0)], "train/agent-1/entropy": [(64, 2.0)]}


@pytest.mark.slow  # compiles a batch trainer
def test_a_batch_too_large_for_memory_is_refused_in_one_line(tmp_path, capsys, monkeypatch):
    needed: list[int] = []
    real = batch_module.compiled_bytes
    monkeypatch.setattr(batch_module, "compiled_bytes",
                        lambda compiled: needed.append(real(compiled)) or needed[-1])
    # a device with 60 % of what XLA's analysis says this batch of three needs (a size not compiled before)
    monkeypatch.setattr(batch_module, "device_memory_bytes", lambda device: needed[-1] * 6 // 10)
    out = tmp_path / "big"
    code, _, err = run_cli(["train-lorenz", *TINY_FLAGS, "--seeds", "0-2", "--out", str(out)], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert needed[-1] > 0 and "3 agents need" in err and "about 1 agents" in err
    assert not out.exists()  # nothing left of the refused run


def test_available_ram_is_the_cpu_limit(tmp_path):
    meminfo = tmp_path / "meminfo"
    meminfo.write_text("MemTotal:       16000000 kB\nMemAvailable:    1234567 kB\n")
    cpu = jax.devices("cpu")[0]
    assert batch_module.device_memory_bytes(cpu, meminfo) == 1234567 * 1024
    assert batch_module.device_memory_bytes(cpu, tmp_path / "missing") is None


@pytest.mark.parametrize(("argv", "needle"), [
    (["--seeds", "0-1", "--seed", "2"], "not both"),
    (["--seeds", "3-1"], "empty seed range"),
    (["--seeds", "1,1"], "seeds repeat"),
    (["--seeds", "0,x"], "--seeds"),
    (["--sweep", "lr=1e-3", "--lr", "1e-3"], "swept or as a flag"),
    (["--sweep", "num_envs=2,4"], "NAME one of lr"),
    (["--sweep", "gamma=0.9,2"], "gamma must be"),
    (["--sweep", "lr=1,1"], "values repeat"),
])
def test_bad_seeds_are_one_line_and_exit_2(argv, needle, tmp_path, capsys):
    code, _, err = run_cli(["train-lorenz", *argv, "--out", str(tmp_path / "run")], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and needle in err
    assert not Path(tmp_path / "run").exists()


TWO_DEVICES = textwrap.dedent("""
    import json
    import jax
    import numpy as np
    from jaxsimrl.agents.ppo import PPOConfig, make_train
    from jaxsimrl.agents.ppo.batch import SeedBatch, seed_keys
    from jaxsimrl.envs.lorenz import Lorenz

    assert len(jax.devices()) == 2, jax.devices()
    config = PPOConfig(num_envs=4, steps_per_update=160, total_steps=480, seq_len=10, num_minibatches=2,
                       lstm_size=16, hidden_sizes=(16, 16), update_epochs=2, updates_per_chunk=3)
    # truncated episodes: returns, resets and bootstraps happen inside the batch
    params = Lorenz().default_params().replace(max_steps=25)
    seeds = [0, 5]
    batch = SeedBatch(make_train(config, Lorenz(), params, devices=jax.devices()), len(seeds))
    state, metrics = batch.run_chunk(batch.init(seed_keys(seeds)))
    out = {"sharding": str(state.obs.sharding),
           "batch": {k: np.asarray(v).T.tolist() for k, v in metrics.items()}}  # (agents, updates)
    single = make_train(config, Lorenz(), params, devices=jax.devices()[:1])
    out["single"] = [{k: np.asarray(v).tolist() for k, v in single.run_chunk(single.init(
        jax.random.PRNGKey(seed)))[1].items()} for seed in seeds]
    print("RESULT" + json.dumps(out))
""")


@pytest.mark.slow  # two-device subprocess training
def test_a_batch_sharded_over_two_devices_matches_single_seed_runs_with_episodes():
    proc = subprocess.run([sys.executable, "-c", TWO_DEVICES], env=two_devices_env(), capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(next(x for x in proc.stdout.splitlines() if x.startswith("RESULT"))[len("RESULT"):])
    assert "spec=P(None, 'envs')" in out["sharding"], out["sharding"]  # envs split, agents not
    for agent, single in enumerate(out["single"]):
        assert sum(single["episodes"]) > 0
        for name, values in single.items():
            np.testing.assert_allclose(out["batch"][name][agent], values, rtol=1e-4, atol=1e-5, err_msg=name)
