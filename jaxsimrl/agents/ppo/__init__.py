"""Pure-JAX PPO (PureJaxRL-style train loop, Brax-style module split).

config.py (PPOConfig) | networks.py (actor-critic, LSTM with episode resets) | distribution.py (Gaussian
squashed into the action box) | normalizer.py (running obs statistics) | acting.py (the network's one
forward step on raw observations, used by Policy.act and load_policy) | rollout.py (experience, RunnerState)
| losses.py (GAE, PPO loss) | learner.py (epochs x minibatches) | train.py (make_train, devices) |
batch.py (SeedBatch: many seeds or a hyperparameter sweep, vmapped in one jitted call) |
policy.py (make_policy) | evaluate.py (scan_episodes, episode_returns over random initial states).
"""

from jaxsimrl.agents.ppo.batch import SeedBatch
from jaxsimrl.agents.ppo.config import PPOConfig
from jaxsimrl.agents.ppo.evaluate import episode_returns
from jaxsimrl.agents.ppo.policy import Policy, PolicyParams, make_policy
from jaxsimrl.agents.ppo.rollout import RunnerState
from jaxsimrl.agents.ppo.train import PPOTrainer, make_train

__all__ = ["PPOConfig", "PPOTrainer", "Policy", "PolicyParams", "RunnerState", "SeedBatch", "episode_returns",
           "make_policy", "make_train"]
