"""Train the paper config (seed 0) for N updates and save the flat parameters after each; argv: OUT.npz N.

Run once per XLA build, e.g. ``XLA_FLAGS=--xla_cpu_max_isa=AVX2 python isa_first_updates.py avx2.npz 2``,
then compare the arrays (isa_checks.json holds the comparison made on 2026-12-06).
"""

import json
import sys
from pathlib import Path

import jax
import numpy as np

from jaxsimrl.agents.ppo import PPOConfig, make_train
from jaxsimrl.envs.lorenz import Lorenz

n = int(sys.argv[2])
cfg = json.loads((Path(__file__).resolve().parents[1] / "lorenz_paper.json").read_text())
cfg["total_steps"] = 8000 * n
cfg["updates_per_chunk"] = 1
config = PPOConfig.from_dict(cfg)
env = Lorenz()
trainer = make_train(config, env, env.default_params())
state = trainer.init(jax.random.PRNGKey(0))
out = {}
for u in range(n):
    state, _ = trainer.run_chunk(state)
    leaves = jax.tree.leaves(state.params)
    out[f"u{u + 1}"] = np.concatenate([np.asarray(x, np.float64).ravel() for x in leaves])
    out[f"obs{u + 1}"] = np.asarray(state.obs, np.float64).ravel()
np.savez(sys.argv[1], **out)
