"""eval-lorenz's uncontrolled rollout (seed 0: the paper's start, 32 random ones; 4000 steps); argv: OUT.npy.

Prints the mean return of the 32 random episodes and saves the positions (33, 4001, 3). Run once per XLA
build, e.g. ``XLA_FLAGS=--xla_cpu_max_isa=AVX2 python isa_eval_batch.py avx2.npy``.
"""

import sys

import jax
import numpy as np

from jaxsimrl.envs.lorenz import Lorenz
from jaxsimrl.evaluation.lorenz_eval import initial_states, rollout, uncontrolled

env = Lorenz()
params = env.default_params()
start_key, act_key = jax.random.split(jax.random.PRNGKey(0))
start = initial_states(env, params, start_key, 32)
base = rollout(env, params, uncontrolled, (), start, act_key)
print("mean", base.reward[1:].sum(axis=1).mean())
np.save(sys.argv[1], base.xyz)
