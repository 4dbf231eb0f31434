"""eval-foam: the config round trip, the log cost parser, seeding of the controllers, CLI errors, and
one real evaluation of a small saved run on the coarse mesh checked against FoamCaseEnv run directly.

The saved run is made here (a train-foam run directory in the documented format: config.json with
"env", "seed", "ppo", "foam" and an orbax checkpoint of a RunnerState): an MLP whose actor bias puts
its mean action near the box's top corner, as a trained policy's would be.
"""

from __future__ import annotations

import csv
import dataclasses
import json
from collections import Counter

import numpy as np
import pytest
from foam_marks import needs_openfoam

from foam_bridge._config import TEST_CONVERGENCE, TRAIN_CONVERGENCE, FoamEnvConfig
from foam_bridge._grid import GridCell, write_grid_csv
from foam_bridge._logparse import solver_cost
from jaxsimrl.apps.foam.config import foam_config_from_json, foam_config_to_json
from jaxsimrl.cli.main import main

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
#: The run's case: SIMPLEC with k/omega 0.8 as the paper's code; a low cap keeps random runs short.
TRAIN_FOAM = FoamEnvConfig(mesh_scale=0.4, simple_variant="SIMPLEC", relax_k_omega=0.8, max_iterations=500)
ACTOR_BIAS = 3.0  # tanh(3) = 0.995: the mean action is 0.2 + 0.75 * 0.9975 = 0.948 on both factors


def save_run(path, foam=TRAIN_FOAM, env="foam", network="mlp"):
    """A train-foam run directory with one checkpoint (update 3) of an untrained-but-biased policy."""
    import jax
    import jax.numpy as jnp

    from jaxsimrl.agents.ppo import PPOConfig
    from jaxsimrl.agents.ppo.networks import initial_carry, make_network
    from jaxsimrl.agents.ppo.normalizer import NormalizerState
    from jaxsimrl.agents.ppo.rollout import RunnerState
    from jaxsimrl.runs.atomic import atomic_write_json
    from jaxsimrl.runs.checkpoint import Checkpoints

    config = PPOConfig(network=network, num_envs=2, steps_per_update=8, total_steps=8, seq_len=4,
                       num_minibatches=1, gamma=1.0)
    obs_dim = foam.observation_size
    carry = initial_carry(config, 2)
    params = make_network(config, 2).init(jax.random.PRNGKey(0), carry, jnp.zeros((1, 2, obs_dim)),
                                          jnp.zeros((1, 2), bool))
    head = [k for k, v in params["params"].items() if isinstance(v, dict) and np.shape(v.get("bias")) == (2,)]
    params["params"][head[0]]["bias"] = jnp.full(2, ACTOR_BIAS)
    normalizer = NormalizerState(jnp.float32(10.0), jnp.full(obs_dim, 1.3, jnp.float32),
                                 jnp.full(obs_dim, 2.0, jnp.float32))
    state = RunnerState(params=params, opt_state=(), normalizer=normalizer, env_state=(),
                        obs=jnp.zeros((2, obs_dim)), starts=jnp.ones(2, bool), carry=carry,
                        episode_return=jnp.zeros(2), rng=jax.random.key_data(jax.random.PRNGKey(1)),
                        update_step=jnp.int32(3))
    path.mkdir(parents=True)
    with Checkpoints(path / "checkpoints") as checkpoints:
        checkpoints.save(3, state, {"update": 3})
    atomic_write_json(path / "config.json", {"env": env, "seed": 0, "ppo": config.to_dict(),
                                             "foam": foam_config_to_json(foam)})
    return path


def run_cli(capsys, *argv):
    try:
        code = main(["eval-foam", *map(str, argv)])
    except SystemExit as exit_:
        code = exit_.code
    captured = capsys.readouterr()
    return code, captured.err, captured.out


# ----- no solver -------------------------------------------------------------------------------------
def test_foam_config_round_trips_through_json():
    cfg = FoamEnvConfig(inlet_velocity=(30.0, 60.0), action_low=(0.3, 0.25), turbulence_fields=("k",),
                        convergence=dict(TEST_CONVERGENCE), residual_features=2, work_dir="/tmp/x")
    data = json.loads(json.dumps(foam_config_to_json(cfg)))
    assert data["action_low"] == [0.3, 0.25] and data["inlet_velocity"] == [30.0, 60.0]
    back = foam_config_from_json(data)
    assert back == cfg and isinstance(back.action_low, tuple) and isinstance(back.inlet_velocity, tuple)
    fixed = foam_config_from_json({**data, "inlet_velocity": 44.2})
    assert fixed.inlet_velocity == 44.2
    assert foam_config_from_json({}) == FoamEnvConfig()  # missing fields take the defaults
    train = foam_config_from_json({"convergence": dict(TRAIN_CONVERGENCE)})
    assert dict(train.convergence) == TRAIN_CONVERGENCE


@pytest.mark.parametrize(("data", "needle"), [
    ({"mesh_size": 1.0}, "unknown foam config key(s): mesh_size"),
    ({"action_low": 0.2}, "action_low"),
    ({"mesh_scale": -1.0}, "mesh_scale"),
    ({"convergence": 5}, "convergence"),
    ([1, 2], "JSON object"),
])
def test_bad_foam_config_is_a_one_line_value_error(data, needle):
    with pytest.raises(ValueError, match="^[^\n]*$") as err:
        foam_config_from_json(data)
    assert needle in str(err.value)


LOG = """Time = 1

smoothSolver:  Solving for Ux, Initial residual = 1, Final residual = 0.004, No Iterations 1
smoothSolver:  Solving for Uy, Initial residual = 0.99, Final residual = 0.07, No Iterations 2
GAMG:  Solving for p, Initial residual = 1, Final residual = 0.09, No Iterations 6
GAMG:  Solving for p, Initial residual = 0.3, Final residual = 0.01, No Iterations 4
smoothSolver:  Solving for omega, Initial residual = 0.01, Final residual = 0.0002, No Iterations 2
smoothSolver:  Solving for k, Initial residual = 0.9, Final residual = 0.05, No Iterations 1
ExecutionTime = 0.5 s  ClockTime = 1 s

Time = 2

smoothSolver:  Solving for Ux, Initial residual = 0.1, Final residual = 0.004, No Iterations 3
GAMG:  Solving for p, Initial residual = 0.2, Final residual = 0.01, No Iterations 7
ExecutionTime = 0.75 s  ClockTime = 1 s
"""


def test_solver_cost_sums_inner_iterations_per_field():
    cost = solver_cost(LOG)
    assert cost.linear_iterations == {"U": 6, "p": 17, "omega": 2, "k": 1}
    assert cost.total == 26 and cost.of("p") == 17 and cost.of("nuTilda") == 0
    assert cost.cpu_time_s == 0.75
    assert solver_cost("").linear_iterations == {} and solver_cost("").cpu_time_s is None


@pytest.fixture(scope="module")
def saved_run(tmp_path_factory):
    return save_run(tmp_path_factory.mktemp("evalfoam") / "run")


@pytest.mark.parametrize("network", ["mlp", "lstm"])
def test_controller_actions_depend_only_on_seed_uid_and_step(tmp_path, network):
    from jaxsimrl.apps.foam.evaluation.controllers import LearnedController, RandomController
    from jaxsimrl.apps.foam.evaluation.policy import load_foam_run
    from jaxsimrl.policy import BatchActor

    run = load_foam_run(save_run(tmp_path / "run", network=network))
    assert run.update == 3 and run.checkpoint_step == 3 and run.config.network == network
    obs_of = {5: [1.3], 7: [0.3]}
    actors = {3: BatchActor(run.policy, 3)}  # one compilation per mode serves every controller and seed

    def learned(deterministic, uids, seed=0, batch=3):
        controller = LearnedController("c", actors[batch], deterministic, seed)
        obs = np.array([obs_of[uid] for uid in uids], np.float32)
        for uid in uids:
            controller.begin(uid)
        first = controller.act(uids, obs, [0] * len(uids))
        return first, controller.act(uids, obs, [1] * len(uids))

    pair, alone = learned(False, [5, 7]), learned(False, [7])
    np.testing.assert_array_equal(pair[0][1], alone[0][0])  # uid 7, whoever shares the batch
    np.testing.assert_array_equal(pair[1][1], alone[1][0])
    actors[1] = BatchActor(run.policy, 1)  # a pool of one pads to another batch size
    np.testing.assert_array_equal(learned(False, [7], batch=1)[0], alone[0])
    assert not np.allclose(pair[0][0], pair[0][1]) and not np.allclose(pair[0][1], pair[1][1])
    assert not np.allclose(learned(False, [7], seed=1)[0], alone[0])
    mean = learned(True, [5, 7])[0]
    np.testing.assert_allclose(mean, 0.2 + 0.75 * (np.tanh(ACTOR_BIAS) + 1) / 2, atol=2e-3)
    for actions in (*pair, *alone):
        assert np.all((actions >= 0.2) & (actions <= 0.95))

    random = RandomController("r", (0.2, 0.2), (0.95, 0.95), seed=0)
    random.begin(5), random.begin(7)
    both = random.act([5, 7], np.zeros((2, 1)), [0, 0])
    again = RandomController("r", (0.2, 0.2), (0.95, 0.95), seed=0)
    again.begin(7)
    np.testing.assert_array_equal(both[1], again.act([7], np.zeros((1, 1)), [0])[0])


class ScriptedBackend:
    """A stand-in for foam_bridge's pool: episode ``uid`` converges after ``lengths[uid]`` steps of 100
    iterations; ``die`` = {uid: step} kills the worker on that step; ``reject`` uids fail their reset."""

    def __init__(self, lengths, die=(), reject=()):
        self.lengths, self.die, self.reject = lengths, dict(die), set(reject)
        self.slot_uid, self.steps, self.stepped = {}, {}, []
        self.stranded = {}  # the pool's record of envs whose worker died beside them: none here

    def node_of(self, env_id):
        return ""

    def run(self, requests):
        from foam_bridge._backends import Reply

        replies = []
        for request in requests:
            slot = request.env_id
            if request.method == "reset":
                uid = request.args["seed"]
                if uid in self.reject:
                    replies.append(Reply(slot, False, error="CaseError: broken", kind="CaseError"))
                    continue
                self.slot_uid[slot], self.steps[uid] = uid, 0
                replies.append(Reply(slot, True, (np.ones(1, np.float32), {})))
                continue
            uid = self.slot_uid[slot]
            self.steps[uid] += 1
            self.stepped.append(uid)
            if self.die.get(uid) == self.steps[uid]:
                replies.append(Reply(slot, False, error="worker died", worker_died=True))
                continue
            done = self.steps[uid] == self.lengths[uid]
            info = {"iterations": 100 * self.steps[uid], "outcome": "converged" if done else "running"}
            if done:
                info["episode"] = {"wall_time_s": 2.0, "solver_idle_s": 0.5, "iterations": info["iterations"],
                                   "actions": [[0.9, 0.8]] * self.steps[uid]}
            replies.append(Reply(slot, True, (np.ones(1, np.float32), -100.0, done, False, info)))
        return replies

    def close(self):
        pass


def _scripted(monkeypatch, backend, lengths, pool):
    from foam_bridge import _batched as batched
    from jaxsimrl.apps.foam.evaluation import runner as foam_runner
    from jaxsimrl.apps.foam.evaluation.controllers import ConstantController

    monkeypatch.setattr(batched, "make_backend", lambda *args, **kwargs: backend)
    jobs = [foam_runner.Job(uid, "c", "h", 50.0, 0) for uid in range(len(lengths))]
    return foam_runner.run_episodes(FoamEnvConfig(), jobs, {"c": ConstantController("c", (0.9, 0.8))}, pool)


@pytest.mark.parametrize("lengths", [[1, 1, 1], [3, 1, 2, 1, 4], [2, 2, 2, 2]])
def test_runner_keeps_slots_busy_and_steps_each_episode_only_to_its_end(monkeypatch, lengths):
    backend = ScriptedBackend(dict(enumerate(lengths)), die={1: 1})
    results = _scripted(monkeypatch, backend, lengths, pool=2)
    assert [r.job.uid for r in results] == list(range(len(lengths)))
    assert backend.steps == {uid: 1 if uid == 1 else n for uid, n in enumerate(lengths)}  # no extra step
    assert results[1].outcome == "crashed" and results[1].cause == "worker died"
    for result in results[:1] + results[2:]:
        assert result.outcome == "converged" and result.iterations == 100 * lengths[result.job.uid]
        assert result.wall_time_s == 1.5 and len(result.actions) == lengths[result.job.uid]
        assert result.cost is None  # no log.simpleFoam behind a scripted backend


def test_runner_stops_on_a_case_the_env_rejects(monkeypatch):
    with pytest.raises(ValueError, match="CaseError: broken"):
        _scripted(monkeypatch, ScriptedBackend({0: 1, 1: 1}, reject={1}), [1, 1], pool=2)


def test_an_episode_keeps_its_uid_whatever_else_the_command_evaluates():
    from jaxsimrl.apps.foam.evaluation.eval import plan
    from jaxsimrl.apps.foam.evaluation.eval_spec import DEFAULT_CONTROLLERS

    repeats = {c: c in ("learned_stochastic", "random") for c in DEFAULT_CONTROLLERS}
    small = plan(["h"], [50.0], repeats, 2)
    large = plan(["h", "2h"], [25.0, 50.0, 75.0], repeats, 10)
    assert len(small) == 3 + 2 * 2 and len(large) == 2 * 3 * (3 + 2 * 10)
    by_name = {(j.controller, j.geometry, j.velocity, j.sample): j.uid for j in large}
    assert all(by_name[(j.controller, j.geometry, j.velocity, j.sample)] == j.uid for j in small)
    assert len(set(by_name.values())) == len(large)
    chosen = {c: repeats[c] for c in ("random", "best_constant")}  # a subset, in CONTROLLERS order
    subset = plan(["h"], [50.0], chosen, 2)
    assert [j.controller for j in subset] == ["best_constant", "random", "random"]
    assert all(by_name[(j.controller, j.geometry, j.velocity, j.sample)] == j.uid for j in subset)


# ----- CLI errors --------------------------------------------------------------------------------------
def _grid_csv(path, cells):
    write_grid_csv(cells, path)
    return path


#: bad input -> what its one-line error says
BAD_INPUT = {"no_config": "not a run directory", "lorenz": "not a train-foam run",
             "no_checkpoint": "no checkpoint", "velocity": "positive", "bad_csv": "not a grid-foam grid.csv",
             "no_csv": "cannot read", "twice": "must be distinct",
             "unconverged_csv": "no converged cell", "wrong_obs": "observations of size 1",
             "controller": "invalid choice", "cache_alone": "reference_cache needs reference_iterations",
             "oracle_axes_alone": "case_oracle controller",
             "cache_file": "exists and is not a directory"}


@pytest.mark.parametrize("case", list(BAD_INPUT))
def test_bad_input_is_one_line_exit_2(capsys, tmp_path, saved_run, case):
    run, extra = saved_run, []
    if case == "no_config":
        run = tmp_path / "empty"
        run.mkdir()
    elif case == "lorenz":
        run = save_run(tmp_path / "lorenz", env="lorenz")
    elif case == "no_checkpoint":
        run = tmp_path / "bare"
        run.mkdir()
        (run / "config.json").write_text((saved_run / "config.json").read_text())
    elif case == "velocity":
        extra = ["--velocities", "50", "-5"]
    elif case == "twice":
        extra = ["--velocities", "50", "25", "50.0"]
    elif case == "bad_csv":
        (tmp_path / "g.csv").write_text("a,b\n1,2\n")
        extra = ["--baseline-grid", tmp_path / "g.csv"]
    elif case == "controller":
        extra = ["--controllers", "random", "oracle"]
    elif case == "oracle_axes_alone":
        extra = ["--oracle-alpha-u", "0.9"]
    elif case == "cache_alone":
        extra = ["--reference-cache", tmp_path / "cache"]
    elif case == "cache_file":
        (tmp_path / "cache").write_text("not a directory")
        extra = ["--reference-iterations", "100", "--reference-cache", tmp_path / "cache"]
    elif case == "no_csv":
        extra = ["--baseline-grid", tmp_path / "missing.csv"]
    elif case == "unconverged_csv":
        extra = ["--baseline-grid", _grid_csv(tmp_path / "g.csv", [GridCell(0.5, 0.5, 90, "crashed", 1.0)])]
    elif case == "wrong_obs":  # the checkpoint's observations do not fit the config's residual features
        run = tmp_path / "mismatch"
        run.mkdir()
        config = json.loads((saved_run / "config.json").read_text())
        config["foam"]["residual_features"] = 2
        (run / "config.json").write_text(json.dumps(config))
        (run / "checkpoints").symlink_to(saved_run / "checkpoints")
    code, err, _ = run_cli(capsys, run, *extra, "--out", tmp_path / "out")
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert BAD_INPUT[case] in err
    assert not (tmp_path / "out").exists()


def test_best_constant_of_a_grid_csv_is_its_fastest_converged_cell(tmp_path):
    from jaxsimrl.apps.foam.evaluation.baseline import baseline_from_csv

    cells = [GridCell(0.95, 0.95, 260, "converged", 1.0), GridCell(0.9, 0.95, 250, "converged", 1.0),
             GridCell(0.5, 0.5, 90, "crashed", 1.0), GridCell(0.7, 0.7, 1000, "truncated", 1.0)]
    baseline = baseline_from_csv(_grid_csv(tmp_path / "grid.csv", cells))
    assert baseline.factors == (0.9, 0.95) and baseline.grid_iterations == 250
    assert str(tmp_path / "grid.csv") in baseline.source


# ----- one real evaluation -----------------------------------------------------------------------------
VELOCITY = 50.0
GRID = ("--grid-alpha-u", "0.95", "--grid-alpha-p", "0.9", "0.95")


@pytest.fixture(scope="module")
def evaluation(saved_run, tmp_path_factory):
    """eval-foam without --baseline-grid: it runs its own 1 x 2 grid for the best constant first."""
    out = tmp_path_factory.mktemp("evalout") / "out"
    code = main(["eval-foam", str(saved_run), "--velocities", str(VELOCITY), "--step-height", "0.0127",
                 "--mesh-scale", "0.4", "--samples", "2", "--pool", "2", *GRID, "--out", str(out)])
    assert code == 0
    return out, json.loads((out / "eval.json").read_text())


@needs_openfoam
def test_eval_writes_its_files_and_one_run_per_deterministic_cell(evaluation):
    out, report = evaluation
    assert sorted(p.name for p in out.iterdir()) == ["baseline_grid.csv", "baseline_grid.png", "box_V50.png",
                                                      "eval.csv", "eval.json", "factors.png", "mean_V50.png",
                                                      "velocities.png"]
    for name in ("box_V50.png", "mean_V50.png", "factors.png", "baseline_grid.png", "velocities.png"):
        assert (out / name).read_bytes()[:8] == PNG_MAGIC
    assert report["geometries"] == {"h": 0.0127} and report["criterion"] == dict(TEST_CONVERGENCE)
    assert report["case"]["simple_variant"] == "SIMPLEC" and report["case"]["relax_k_omega"] == 0.8
    assert report["checkpoint_update"] == 3
    expected_runs = {"learned_deterministic": 1, "learned_stochastic": 2, "best_constant": 1,
                     "tutorial_defaults": 1, "random": 2}
    results = report["results"]
    for controller, runs in expected_runs.items():
        cell = results[controller]["h"]["50"]
        assert len(cell["runs"]) == runs and sum(cell["outcomes"].values()) == runs
        assert cell["iterations"]["n"] == cell["converged"] and cell["penalised_iterations"]["n"] == runs
        if cell["converged"]:  # runs that did not converge count at the cap (500) in the penalised mean
            assert cell["penalised_iterations"]["mean"] >= cell["iterations"]["mean"]
        for run in cell["runs"]:
            assert run["outcome"] in ("converged", "truncated", "crashed", "diverged", "hung")
            assert run["steps"] == len(run["actions"]) >= 1
            assert run["wall_time_s"] > 0 and run["cpu_time_s"] > 0
            # every SIMPLE iteration solves U, p, k and omega at least once
            assert run["linear_iterations"] >= 4 * run["iterations"] > 0
            assert 0 < run["p_linear_iterations"] < run["linear_iterations"]
    learned = results["learned_deterministic"]["h"]["50"]["runs"][0]
    np.testing.assert_allclose(learned["actions"], 0.948, atol=2e-3)
    assert learned["outcome"] == "converged"
    assert all(run["actions"][0] == [0.9, 0.8] for run in results["tutorial_defaults"]["h"]["50"]["runs"])
    random_runs = results["random"]["h"]["50"]["runs"]
    assert random_runs[0]["actions"] != random_runs[1]["actions"]
    with open(out / "eval.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == sum(expected_runs.values())
    assert Counter(r["controller"] for r in rows) == expected_runs


@needs_openfoam
def test_best_constant_is_the_grids_best_and_matches_the_env_run_directly(evaluation, tmp_path):
    from foam_bridge._env import FoamCaseEnv
    from foam_bridge._grid import best_cell, read_grid_csv
    from foam_bridge._logparse import read_solver_cost

    out, report = evaluation
    cells = read_grid_csv(out / "baseline_grid.csv")
    assert sorted((c.alpha_u, c.alpha_p) for c in cells) == [(0.95, 0.9), (0.95, 0.95)]
    best = best_cell(cells)
    factors = (report["baseline"]["alpha_u"], report["baseline"]["alpha_p"])
    assert factors == (best.alpha_u, best.alpha_p)
    assert report["baseline"]["grid_iterations"] == best.iterations
    assert "grid run by eval-foam at V = 50 m/s on h" in report["baseline"]["source"]
    run = report["results"]["best_constant"]["h"]["50"]["runs"][0]
    assert all(action == list(factors) for action in run["actions"])
    assert run["iterations"] == best.iterations  # the grid ran the same case under the same criterion
    cfg = dataclasses.replace(TRAIN_FOAM, convergence=dict(TEST_CONVERGENCE), keep_cases=True,
                              work_dir=tmp_path)
    with FoamCaseEnv(cfg) as env:
        env.reset(seed=0, options={"inlet_velocity": VELOCITY})
        done = False
        while not done:
            _, _, terminated, truncated, info = env.step(factors)
            done = terminated or truncated
        cost = read_solver_cost(env.case_dir)
    assert info["outcome"] == run["outcome"] == "converged"
    assert run["iterations"] == info["iterations"]
    assert run["linear_iterations"] == cost.total and run["p_linear_iterations"] == cost.of("p")


@pytest.mark.slow  # a grid of real runs
@needs_openfoam
def test_the_case_oracle_runs_its_grid_on_the_case_and_keeps_the_best(saved_run, tmp_path, capsys):
    out = tmp_path / "oracle"
    code = main(["eval-foam", str(saved_run), "--velocities", str(VELOCITY), "--step-height", "0.0127",
                 "--mesh-scale", "0.4", "--pool", "2", "--controllers", "case_oracle", "tutorial_defaults",
                 "--oracle-alpha-u", "0.9", "--oracle-alpha-p", "0.8", "0.95", "--out", str(out)])
    assert code == 0
    report = json.loads((out / "eval.json").read_text())
    assert list(report["results"]) == ["tutorial_defaults", "case_oracle"] and report["baseline"] is None
    cell = report["results"]["case_oracle"]["h"]["50"]
    oracle = cell["oracle"]
    assert [g["factors"] for g in oracle["grid"]] == [[0.9, 0.8], [0.9, 0.95]] and oracle["solver_runs"] == 2
    assert oracle["simple_iterations"] == sum(g["iterations"] for g in oracle["grid"])
    # the grid's (0.9, 0.8) cell is the tutorial's own settings on the same case: the same run
    (defaults,) = report["results"]["tutorial_defaults"]["h"]["50"]["runs"]
    assert (oracle["grid"][0]["outcome"], oracle["grid"][0]["iterations"]) == (defaults["outcome"],
                                                                               defaults["iterations"])
    converged = [g for g in oracle["grid"] if g["outcome"] == "converged"]
    (run,) = cell["runs"]  # the oracle's result: its grid's fastest converged run
    expected = min(converged, key=lambda g: g["iterations"]) if converged else oracle["grid"][0]
    assert oracle["factors"] == expected["factors"] and run["iterations"] == expected["iterations"]
    assert all(action == expected["factors"] for action in run["actions"])
    with open(out / "eval.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert Counter(r["controller"] for r in rows) == {"case_oracle": 1, "case_oracle_grid": 1,
                                                      "tutorial_defaults": 1}
    assert (out / "box_V50.png").read_bytes()[:8] == PNG_MAGIC
    printed = capsys.readouterr().out
    assert f"case oracle h V=50: ({', '.join(f'{f:g}' for f in expected['factors'])}) of a grid of 2 runs" \
        in printed


def _run_directly(cfg, uid, factors, case_copy):
    """One episode with constant factors on FoamCaseEnv itself; returns its record and final U field."""
    import shutil

    from foam_bridge._env import FoamCaseEnv
    from foam_bridge._fields import final_field

    with FoamCaseEnv(dataclasses.replace(cfg, keep_cases=True), work_dir=case_copy.parent / "work") as env:
        env.reset(seed=uid, options={"inlet_velocity": VELOCITY})
        done = False
        while not done:
            _, _, terminated, truncated, info = env.step(factors)
            done = terminated or truncated
        shutil.copytree(env.case_dir, case_copy, ignore=shutil.ignore_patterns("foamBridge"))
    return info, final_field(case_copy, "U")


@pytest.mark.slow  # evaluation and another eval-foam run
@needs_openfoam
def test_a_subset_of_controllers_runs_only_those_and_the_same_episodes(evaluation, saved_run, tmp_path):
    from foam_bridge._config import without_convergence_test
    from foam_bridge._fields import relative_l2
    from jaxsimrl.apps.foam.evaluation.eval_spec import REFERENCE, episode_uid

    full_out, full = evaluation
    out = tmp_path / "subset"
    code = main(["eval-foam", str(saved_run), "--velocities", str(VELOCITY), "--step-height", "0.0127",
                 "--mesh-scale", "0.4", "--samples", "2", "--pool", "2", "--out", str(out),
                 "--controllers", "tutorial_defaults", "learned_deterministic",
                 "--reference-iterations", "600", "--confirm-alpha-u", "0.9"])
    assert code == 0
    report = json.loads((out / "eval.json").read_text())
    # every run's convergence checked at alpha_u 0.9: both controllers end at or above it, so their
    # runs pass at once and stay the same episodes as the full evaluation's (which had no check)
    assert report["case"]["confirm_alpha_u"] == 0.9 and full["case"]["confirm_alpha_u"] is None
    assert [report["results"][c]["h"]["50"]["failed_checks"] for c in report["results"]] == [0, 0]
    # no best constant asked for: no grid is run, and the report says there is no baseline
    assert "baseline_grid.csv" not in {p.name for p in out.iterdir()} and report["baseline"] is None
    assert list(report["results"]) == list(report["controllers"]) == ["learned_deterministic",
                                                                         "tutorial_defaults"]
    for controller in report["results"]:
        (run,) = report["results"][controller]["h"]["50"]["runs"]
        (same,) = full["results"][controller]["h"]["50"]["runs"]
        assert (run["iterations"], run["outcome"], run["actions"]) == (
            same["iterations"], same["outcome"], same["actions"])
        assert same["u_error"] is None  # the full evaluation had no reference

    # the reference: the defaults (no best constant) for exactly 600 iterations, no convergence test
    reference = report["reference"]
    assert reference["iterations"] == 600 and reference["factors"] == [0.9, 0.8]
    ref_run = reference["runs"]["h"]["50"]
    assert (ref_run["outcome"], ref_run["iterations"], ref_run["has_field"]) == ("truncated", 600, True)

    # every run's U error is the distance of its final field from the reference's, computed here again
    # from FoamCaseEnv runs of the same episodes
    cfg = dataclasses.replace(TRAIN_FOAM, convergence=dict(TEST_CONVERGENCE))
    long_cfg = dataclasses.replace(without_convergence_test(cfg), max_iterations=600)
    info, ref_field = _run_directly(long_cfg, episode_uid(REFERENCE, "h", VELOCITY, 0), (0.9, 0.8),
                                    tmp_path / "ref")
    assert info["iterations"] == 600
    run = report["results"]["tutorial_defaults"]["h"]["50"]["runs"][0]
    info, field = _run_directly(cfg, episode_uid("tutorial_defaults", "h", VELOCITY, 0), (0.9, 0.8),
                                tmp_path / "defaults")
    assert info["iterations"] == run["iterations"]
    assert run["u_error"] == pytest.approx(relative_l2(field[1], ref_field[1]), rel=1e-9)
    assert 0 < run["u_error"] < 1
    cell = report["results"]["learned_deterministic"]["h"]["50"]
    assert cell["u_error"]["n"] == cell["converged"] and cell["runs"][0]["u_error"] > 0
    with open(out / "eval.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [float(r["u_error"]) for r in rows] == pytest.approx(
        [cell["runs"][0]["u_error"], run["u_error"]])


@pytest.mark.slow  # several eval-foam runs
@needs_openfoam
def test_a_reference_cache_reuses_a_reference_only_for_the_same_inputs(saved_run, tmp_path):
    cache = tmp_path / "cache"

    def evaluate(name, iterations):
        out = tmp_path / name
        assert main(["eval-foam", str(saved_run), "--velocities", str(VELOCITY), "--step-height", "0.0127",
                     "--mesh-scale", "0.4", "--pool", "1", "--controllers", "tutorial_defaults",
                     "--reference-iterations", str(iterations), "--reference-cache", str(cache),
                     "--out", str(out)]) == 0
        report = json.loads((out / "eval.json").read_text())
        return report["reference"]["runs"]["h"]["50"], \
            report["results"]["tutorial_defaults"]["h"]["50"]["runs"][0]["u_error"]

    first, first_error = evaluate("first", 300)
    second, second_error = evaluate("second", 300)
    other, other_error = evaluate("other", 320)  # another reference length: another reference
    assert (first["cached"], second["cached"], other["cached"]) == (False, True, False)
    assert second["final_residuals"] == first["final_residuals"] and second["iterations"] == 300
    assert second_error == first_error and other_error != first_error and other["iterations"] == 320
    entries = sorted(cache.glob("*.json"))
    assert len(entries) == 2 and len(list(cache.glob("*.npz"))) == 2
    # an entry that lost its field is a miss: the reference runs again and is stored again
    (short,) = [e for e in entries if json.loads(e.read_text())["iterations"] == 300]
    short.with_suffix(".npz").unlink()
    again, again_error = evaluate("again", 300)
    assert not again["cached"] and again_error == first_error and len(list(cache.glob("*.npz"))) == 2


@needs_openfoam
def test_the_reference_key_follows_the_case_files_and_not_where_they_run(tmp_path):
    import shutil

    from foam_bridge._template import TEMPLATE_DIR
    from jaxsimrl.apps.foam.evaluation.reference_cache import reference_keys

    def reference_key(cfg, velocity, factors):
        return reference_keys(cfg, [velocity], factors)[velocity]

    case = tmp_path / "case"
    shutil.copytree(TEMPLATE_DIR, case)
    cfg = FoamEnvConfig(case_dir=str(case), mesh_scale=0.4)
    key = reference_key(cfg, 50.0, (0.95, 0.875))
    assert reference_keys(cfg, [25.0, 50.0], (0.95, 0.875))[50.0] == key  # one velocity's key, alone or not
    assert reference_key(dataclasses.replace(cfg, work_dir=str(tmp_path / "w"), step_timeout_s=7.0),
                         50.0, (0.95, 0.875)) == key
    (case / "100").mkdir()
    (case / "100" / "U").write_text("earlier output")  # a time directory left by an earlier run
    assert reference_key(cfg, 50.0, (0.95, 0.875)) == key
    assert reference_key(cfg, 50.5, (0.95, 0.875)) != key
    assert reference_key(cfg, 50.0, (0.95, 0.9)) != key
    assert reference_key(dataclasses.replace(cfg, relax_k_omega=0.9), 50.0, (0.95, 0.875)) != key
    with open(case / "system" / "fvSchemes", "a") as handle:
        handle.write("// edited\n")
    assert reference_key(cfg, 50.0, (0.95, 0.875)) != key


@needs_openfoam
@pytest.mark.slow  # three eval-foam runs and one FoamCaseEnv run (~1 min)
def test_the_no_training_rules_run_in_the_protocol_at_their_own_step_length(saved_run, tmp_path):
    """``--controllers residual_rule bandit``: solve's rules, from the tutorial's defaults in the training
    box, each stepping at its own interval; the residual rule's run is the episode FoamCaseEnv gives when
    the rule acts on its residuals directly."""
    from foam_bridge._env import FoamCaseEnv
    from jaxsimrl.apps.foam.evaluation.eval_spec import episode_uid
    from jaxsimrl.apps.foam.solve.rules import INTERVALS, ResidualRule

    out = tmp_path / "rules"
    code = main(["eval-foam", str(saved_run), "--velocities", str(VELOCITY), "--step-height", "0.0127",
                 "--mesh-scale", "0.4", "--pool", "2", "--controllers", "residual_rule", "bandit",
                 "tutorial_defaults", "--out", str(out)])
    assert code == 0
    report = json.loads((out / "eval.json").read_text())
    assert list(report["results"]) == ["tutorial_defaults", "residual_rule", "bandit"]
    runs = {name: report["results"][name]["h"]["50"]["runs"] for name in report["results"]}
    assert all(len(cell) == 1 for cell in runs.values())
    for name, rule in (("residual_rule", "residual-rule"), ("bandit", "bandit")):
        (run,) = runs[name]
        assert run["steps"] == len(run["actions"]) == -(-run["iterations"] // INTERVALS[rule])
        assert all(0.2 - 1e-6 <= a <= 0.95 + 1e-6 for action in run["actions"] for a in action)
    assert runs["bandit"][0]["actions"][0] == pytest.approx([0.9, 0.8])  # arm 0: the case's own
    assert runs["residual_rule"][0]["actions"][0] == pytest.approx([0.95, 0.95])  # SIMPLEC: the box's top

    cfg = dataclasses.replace(TRAIN_FOAM, convergence=dict(TEST_CONVERGENCE),
                              interval=INTERVALS["residual-rule"])
    rule = ResidualRule(dict(TEST_CONVERGENCE), (0.9, 0.8), cfg.action_low, cfg.action_high, simplec=True)
    actions, residuals = [], None
    with FoamCaseEnv(cfg, work_dir=tmp_path / "direct") as env:
        env.reset(seed=episode_uid("residual_rule", "h", VELOCITY, 0), options={"inlet_velocity": VELOCITY})
        done = False
        while not done:
            actions.append(rule.act(None, residuals))
            _, _, terminated, truncated, info = env.step(np.asarray(actions[-1]))
            residuals, done = info["residuals"], terminated or truncated
    (run,) = runs["residual_rule"]
    assert (run["iterations"], run["outcome"]) == (info["iterations"], info["outcome"])
    np.testing.assert_allclose(run["actions"], actions, atol=1e-6)
