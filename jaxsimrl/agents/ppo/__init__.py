"""Pure-JAX PPO (PureJaxRL-style train loop, Brax-style module split).

config.py (PPOConfig) | networks.py (actor-critic, LSTM with episode resets) | distribution.py (Gaussian
squashed into the action box) | normalizer.py (running obs statistics) | acting.py (the network's one
forward step on raw observations, used by Policy.act and load_policy) | rollout.py (experience, RunnerState)
| losses.py (GAE, PPO loss) | learner.py (epochs x minibatches) | train.py (make_train, devices) |
batch.py (SeedBatch: many seeds or a hyperparameter sweep, vmapped in one jitted call) |
policy.py (make_policy) | evaluate.py (scan_episodes, episode_returns over random initial states).
"""

import importlib
from typing import Any

# name -> module: imported on first use, so that acting with a trained policy (jaxsimrl.policy, solve)
# does not load the trainer (optax, the rollout, distrax for sampling) it never calls
_EXPORTS = {"SeedBatch": "batch", "PPOConfig": "config", "episode_returns": "evaluate",
            "Policy": "policy", "PolicyParams": "policy", "make_policy": "policy", "RunnerState": "rollout",
            "PPOTrainer": "train", "make_train": "train"}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)
