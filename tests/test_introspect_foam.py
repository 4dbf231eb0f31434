"""load_policy on a train-foam run (the small run committed beside the foam notebook): acting in the
env's units inside its box, the same actions as eval-foam's actor, one-line errors for damaged runs;
the 1-D profile and factor-history helpers on hand-built inputs with known answers; and one real
rollout on the coarse mesh (mesh_scale 0.4) whose record adds up."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from foam_marks import needs_openfoam

import jaxsimrl
from foam_bridge._config import U_REF, FoamEnvConfig
from jaxsimrl.apps.foam.introspect import factor_history, plot_factor_history
from jaxsimrl.apps.foam.spec import foam_obs_names
from jaxsimrl.introspect import plot_policy_profile, policy_profile

RUN = Path(__file__).resolve().parents[1] / "experiments" / "notebooks" / "foam_small_run"
STATES = np.linspace(0.0, 6.0, 13)[:, None]  # beyond both ends of what training saw (0.6 .. 2.2)


@pytest.fixture(scope="module")
def policy():
    return jaxsimrl.load_policy(RUN)


def test_a_train_foam_run_loads_and_acts_in_its_box(policy):
    assert policy.record["env"] == "foam" and isinstance(policy.env_params, FoamEnvConfig)
    assert policy.env_params.mesh_scale == 0.4 and policy.config.network == "mlp"
    assert policy.obs_names == ("state",) and policy.action_names == ("alpha_u", "alpha_p")
    assert (policy.update, policy.env_steps) == (7, 56)
    np.testing.assert_allclose(policy.action_low, [0.2, 0.2])
    np.testing.assert_allclose(policy.action_high, [0.95, 0.95])
    actions, _ = policy.act(STATES)
    assert actions.shape == (13, 2) and np.all((actions >= 0.2) & (actions <= 0.95))
    assert np.ptp(actions, axis=0).min() > 0.05  # the action does depend on the state
    single, _ = policy.act(STATES[3])
    np.testing.assert_allclose(single, actions[3], rtol=1e-6)
    np.testing.assert_allclose(policy.distribution(STATES).median, actions, rtol=1e-6)
    sampled, _ = policy.act(STATES, deterministic=False, key=0)
    assert np.all((sampled >= 0.2) & (sampled <= 0.95)) and not np.allclose(sampled, actions)
    values = policy.value(STATES)
    trained = (STATES[:, 0] > 0.6) & (STATES[:, 0] < 2.2)  # initial states at 35 .. 65 m/s
    assert values.shape == (13,) and np.all(values[trained] < 0)  # minus iterations still to go


def test_acting_is_eval_foams_actor(policy):
    from jaxsimrl.apps.foam.evaluation.policy import load_foam_run
    from jaxsimrl.policy import BatchActor

    actor = BatchActor(load_foam_run(RUN).policy, 13)
    carries = [actor.initial_carry()] * 13
    theirs, _ = actor.act(STATES, carries, list(range(13)), [0] * 13, deterministic=True)
    np.testing.assert_allclose(policy.act(STATES)[0], theirs, rtol=1e-6)


@pytest.mark.slow  # trains a recurrent policy
def test_a_recurrent_foam_policy_carries_its_memory_as_eval_foams_actor_does(tmp_path):
    from test_eval_foam import save_run

    from jaxsimrl.policy import BatchActor

    run = save_run(tmp_path / "lstm", network="lstm")
    policy = jaxsimrl.load_policy(run)
    assert policy.recurrent and policy.obs_names == ("state",)
    actor = BatchActor(policy, 1)
    obs, state, carries = np.array([[1.3], [0.4], [2.0]], np.float32), None, [actor.initial_carry()]
    for step, row in enumerate(obs):
        mine, state = policy.act(row, state)
        theirs, carries = actor.act(row[None], carries, [0], [step], deterministic=True)
        np.testing.assert_allclose(mine, theirs[0], rtol=1e-5)
    np.testing.assert_allclose(state[1], carries[0][1], rtol=1e-5)  # the same hidden state


def _damaged(tmp_path, how):
    run = tmp_path / "run"
    shutil.copytree(RUN, run)
    config = json.loads((run / "config.json").read_text())
    if how == "residual_features":
        config["foam"]["residual_features"] = 1
    elif how == "no_foam":
        del config["foam"]
    elif how == "bad_foam":
        config["foam"]["mesh_scale"] = -1.0
    else:
        shutil.rmtree(run / "checkpoints")
        (run / "checkpoints").mkdir()
    (run / "config.json").write_text(json.dumps(config))
    return run


@pytest.mark.parametrize(("how", "needle"), [
    ("residual_features", "observations of size 1, but its config.json's env gives 5"),
    ("no_foam", "no 'foam' section"),
    ("bad_foam", "mesh_scale"),
    ("no_checkpoint", "checkpoint"),
])
def test_a_damaged_foam_run_is_a_one_line_error(tmp_path, how, needle):
    with pytest.raises(ValueError, match="^[^\n]*$") as err:
        jaxsimrl.load_policy(_damaged(tmp_path, how))
    assert needle in str(err.value)


def test_observation_names_follow_the_residual_features():
    cfg = FoamEnvConfig(residual_features=2, convergence={"U": 1e-3, "p": 5e-2})
    assert foam_obs_names(cfg) == ("state", "log10 r_U (t-1)", "log10 r_p (t-1)", "log10 r_U", "log10 r_p")
    assert len(foam_obs_names(cfg)) == cfg.observation_size


def test_rollout_refuses_bad_options_before_any_solver(policy):
    cases = [({"steps": 3}, "max_iterations"), ({"velocities": [50.0, 50.0]}, "distinct"),
             ({"velocities": [-1.0]}, "> 0"), ({"velocities": "fast"}, "> 0"), ({"velocities": []}, "> 0"),
             ({"pool": 0}, "pool"),
             ({"env_params": dataclasses.replace(policy.env_params, residual_features=1)}, "size 5"),
             ({"env_params": {"mesh_scale": 0.4}}, "FoamEnvConfig")]
    for kwargs, needle in cases:
        with pytest.raises(ValueError, match=needle):
            policy.rollout(**kwargs)


def test_a_lorenz_rollout_refuses_the_foam_options():
    import jax
    from test_introspect import LSTM, fresh_params

    from jaxsimrl.introspect import LoadedPolicy

    lorenz = LoadedPolicy.from_params(LSTM, fresh_params(LSTM, jax.random.PRNGKey(0)))
    with pytest.raises(ValueError, match="unknown option.*velocities"):
        lorenz.rollout(steps=5, velocities=[50.0])


class LinearFoamPolicy:
    """actions = W state + b, value = -100 state: the interface the profile helper uses."""

    obs_dim, obs_names, action_names = 1, ("state",), ("alpha_u", "alpha_p")
    W, B = np.array([0.1, -0.05]), np.array([0.4, 0.9])

    def act(self, obs, state=None):
        return np.asarray(obs) @ self.W[None] + self.B, state

    def value(self, obs, state=None):
        return -100.0 * np.asarray(obs)[:, 0]


def test_profile_of_a_linear_policy_is_its_line():
    data = policy_profile(LinearFoamPolicy(), "state", (0.5, 2.5), resolution=5)
    np.testing.assert_allclose(data.x, [0.5, 1.0, 1.5, 2.0, 2.5])
    np.testing.assert_allclose(data.actions[3], [0.6, 0.8])
    np.testing.assert_allclose(data.values, -100 * data.x)
    fig = plot_policy_profile(data, points=(np.array([1.0, 2.0]), np.array([[0.5, 0.85], [0.6, 0.8]])))
    assert len(fig.axes) == 3
    np.testing.assert_allclose(fig.axes[1].lines[0].get_ydata(), data.actions[:, 1])
    np.testing.assert_allclose(fig.axes[0].collections[0].get_offsets(), [[1.0, 0.5], [2.0, 0.6]])
    with pytest.raises(ValueError, match="unknown observation component"):
        policy_profile(LinearFoamPolicy(), "speed", (0, 1))


def _record(episodes):
    """A rollout-shaped record: episodes = [(velocity, [(alpha_u, alpha_p, iterations, r_p), ...])]."""
    columns = {key: [] for key in ("episode", "velocity", "action", "iterations_before", "iterations",
                                   "residual.p", "outcome")}
    for e, (velocity, steps) in enumerate(episodes):
        before = 0
        for t, (alpha_u, alpha_p, iterations, residual) in enumerate(steps):
            for key, value in zip(columns, (e, velocity, [alpha_u, alpha_p], before, iterations, residual,
                                            "converged" if t == len(steps) - 1 else "running"), strict=True):
                columns[key].append(value)
            before = iterations
    return {key: np.array(values) for key, values in columns.items()}


def test_factor_history_pairs_each_action_with_where_it_took_over_and_what_it_answered():
    record = _record([(40.0, [(0.9, 0.3, 100, 1e-1), (0.8, 0.4, 200, 1e-2), (0.7, 0.5, 250, 1e-3)]),
                      (60.0, [(0.6, 0.6, 100, 2e-1), (0.5, 0.7, 180, 2e-2)])])
    data = factor_history(record, residual="p")
    np.testing.assert_allclose(data.velocity, [40.0, 60.0])
    np.testing.assert_array_equal(data.final_iterations, [250, 180])
    assert data.outcome == ("converged", "converged")
    np.testing.assert_array_equal(data.iteration[0], [0, 100, 200])
    np.testing.assert_allclose(data.factors[1], [[0.6, 0.6], [0.5, 0.7]])
    np.testing.assert_allclose(data.residual[0], [np.nan, 1e-1, 1e-2])  # answered: the step before's
    fig = plot_factor_history(data)
    alpha_u_vs_iteration = fig.axes[0].lines
    assert len(alpha_u_vs_iteration) == 2
    np.testing.assert_allclose(alpha_u_vs_iteration[0].get_xdata(), [0, 100, 200, 250])
    np.testing.assert_allclose(alpha_u_vs_iteration[0].get_ydata(), [0.9, 0.8, 0.7, 0.7])
    with pytest.raises(ValueError, match="no residual of 'omega'"):
        factor_history(record, residual="omega")


@pytest.mark.slow  # a whole real rollout
@needs_openfoam
def test_a_real_rollout_on_the_coarse_mesh_adds_up(policy):
    short = dataclasses.replace(policy.env_params, max_iterations=300)  # three steps, then truncated
    record = policy.rollout(short, velocities=[45.0])
    assert len(record["step"]) == 3 and list(record["step"]) == [0, 1, 2]
    assert list(record["outcome"]) == ["running", "running", "truncated"]
    assert -record["reward"].sum() == record["iterations"][-1] == 300
    np.testing.assert_array_equal(record["iterations_before"], [0, 100, 200])
    np.testing.assert_allclose(record["obs"][0, 0], (45.0 / U_REF) ** 2, rtol=1e-5)  # the initial state
    np.testing.assert_allclose(record["action"], policy.act(record["obs"])[0], rtol=1e-5)
    np.testing.assert_allclose(record["value"], policy.value(record["obs"]), rtol=1e-5)
    assert np.all(record["residual.p"] > 0) and set(record["velocity"]) == {45.0}
    history = factor_history(record)
    assert history.factors[0].shape == (3, 2) and history.final_iterations[0] == 300
