"""The OpenFOAM application: simpleFoam's under-relaxation as a control problem, on top of the core.

It reaches the solver through ``foam_bridge`` (which knows nothing of JAX or of this trainer) and the
core through its public modules; the core finds it through ``APP`` (jaxsimrl.apps). Its parts:

- ``config``, ``vec_env``, ``episodes``, ``plan``, ``training``: train-foam (PPO on real simpleFoam runs);
- ``spec``: a train-foam run's env rebuilt from its config.json (policy loading);
- ``evaluation``: eval-foam, the constant-factor baselines and their grids; ``introspect``: rollouts and
  factor histories of a trained policy;
- ``solve``: ``jaxsimrl solve`` on a user's own case; ``controllers``: the controller it ships;
- ``cli``: the subcommands (grid-foam, train-foam, eval-foam, solve, family, generate-cases).
"""

from jaxsimrl.plugin import App

#: foam_bridge._env.FAILURES, spelled out so that finding the application imports nothing of foam_bridge
#: (tests/test_plugin_boundary.py holds the two equal).
FAILED_OUTCOMES = frozenset({"crashed", "diverged", "hung"})

APP = App(
    env="foam",
    commands=tuple(f"jaxsimrl.apps.foam.cli.{name}"
                   for name in ("grid_foam", "train_foam", "eval_foam", "solve", "family", "generate_cases")),
    env_spec="jaxsimrl.apps.foam.spec:foam_spec",
    rollout="jaxsimrl.apps.foam.introspect.rollout:foam_rollout",
    failed_outcomes=FAILED_OUTCOMES,
)
