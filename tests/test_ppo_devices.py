"""Sharding the envs over 2 (CPU) devices learns exactly what 1 device learns with the same batch.

XLA_FLAGS must be set before jax is imported, so the comparison runs in a fresh subprocess.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import pytest

pytestmark = pytest.mark.slow  # two PPO trainings in a subprocess that compiles them afresh

SCRIPT = textwrap.dedent("""
    import json
    import jax
    import numpy as np
    from jaxsimrl.agents.ppo import PPOConfig, make_train
    from jaxsimrl.envs.lorenz import Lorenz

    assert len(jax.devices()) == 2, jax.devices()
    config = PPOConfig(num_envs=4, steps_per_update=160, total_steps=480, seq_len=10, num_minibatches=2,
                       lstm_size=16, hidden_sizes=(16, 16), update_epochs=2, updates_per_chunk=3)
    env = Lorenz()
    # truncate episodes inside the run so resets and bootstraps happen on both devices
    params = env.default_params().replace(max_steps=25)
    out = {}
    for n in (1, 2):
        trainer = make_train(config, env, params, devices=jax.devices()[:n])
        state, metrics = trainer.train(jax.random.PRNGKey(0))
        leaves = [np.asarray(x).ravel() for x in jax.tree.leaves(state.params)]
        out[n] = {"metrics": {k: np.asarray(v).tolist() for k, v in metrics.items()},
                  "params": np.concatenate(leaves).tolist(),
                  "norm_mean": np.asarray(state.normalizer.mean).tolist(),
                  "obs": np.asarray(state.obs).tolist(),
                  "sharding": str(state.obs.sharding)}
    from jaxsimrl.envs.host import HostVecEnv
    from test_vec_env import HOST, CountdownBatch
    try:
        make_train(HOST, vec=HostVecEnv(CountdownBatch(3)))
    except ValueError as err:
        out["host_error"] = str(err)
    print("RESULT" + json.dumps(out))
""")


def two_devices_env() -> dict[str, str]:
    """The environment of a subprocess whose JAX sees 2 CPU devices, keeping the session's XLA flags
    (tests/conftest.py)."""
    flags = f"{os.environ.get('XLA_FLAGS', '')} --xla_force_host_platform_device_count=2".strip()
    return {**os.environ, "XLA_FLAGS": flags, "JAX_PLATFORMS": "cpu"}


def test_two_devices_learn_the_same_as_one():
    env = two_devices_env()
    env["PYTHONPATH"] = os.pathsep.join([os.path.dirname(__file__), env.get("PYTHONPATH", "")])
    proc = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    line = next(x for x in proc.stdout.splitlines() if x.startswith("RESULT"))
    out = json.loads(line[len("RESULT"):])
    one, two = out["1"], out["2"]
    assert one["metrics"]["episodes"] == two["metrics"]["episodes"] and sum(one["metrics"]["episodes"]) > 0
    for name, values in one["metrics"].items():
        assert _close(values, two["metrics"][name], 1e-4), name
    assert _close(one["params"], two["params"], 1e-4)
    assert _close(one["norm_mean"], two["norm_mean"], 1e-5)
    assert _close(one["obs"], two["obs"], 1e-3)
    # host envs: one device, and a clear error on more
    assert out["host_error"].startswith("a host env batch is stepped whole, from one device; got 2")


def _close(a, b, tol):
    import numpy as np

    return np.allclose(np.asarray(a, float), np.asarray(b, float), rtol=tol, atol=tol, equal_nan=True)
