"""The trained policy: one home below evaluation, introspection and solve.

- :func:`load_policy` / :func:`load_agents`: a run directory's checkpoint as a :class:`TrainedPolicy`
  (acting with ``act``/``distribution``/``value``; no plotting, no rollouts, no matplotlib);
- :class:`EnvSpec` / :func:`env_spec`: the action box, params and component names of the env a run
  trained on, from its config.json;
- :class:`BatchActor`: the policy acting for a batch of episodes at their own pace, keyed per
  (seed, episode, step) (eval-foam's learned controllers, foam rollouts);
- :class:`ActionDistribution`: the squashed Gaussian of an action, in env units.

All acting goes through one inference function, :meth:`jaxsimrl.agents.ppo.policy.Policy.act` (batched,
keyed, deterministic or sampled), the one the trainer uses. Layers: agents.ppo < policy < evaluation <
introspect (rollouts, plots; ``jaxsimrl.load_policy``) and solve.
"""

from jaxsimrl.agents.ppo.policy import ActionBox
from jaxsimrl.policy.actor import BatchActor
from jaxsimrl.policy.distribution import ActionDistribution
from jaxsimrl.policy.loading import load_agents, load_policy
from jaxsimrl.policy.spec import EnvSpec, env_spec
from jaxsimrl.policy.trained import TrainedPolicy

__all__ = ["ActionBox", "ActionDistribution", "BatchActor", "EnvSpec", "TrainedPolicy", "env_spec",
           "load_agents", "load_policy"]
