"""``load_policy(run_dir)`` (also ``jaxsimrl.load_policy``): a trained policy that can also roll itself out.

A :class:`LoadedPolicy` is a :class:`jaxsimrl.policy.TrainedPolicy` (loading, acting, the action
distribution and the value live there, one layer down) plus :meth:`LoadedPolicy.rollout` in the run's
env: a jitted scan for a pure-JAX env (:mod:`jaxsimrl.introspect.trajectory`), else its application's
rollout (the App's ``rollout``, jaxsimrl.apps: real simpleFoam episodes for a train-foam run).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from jaxsimrl.introspect.trajectory import rollout
from jaxsimrl.plugin import application, load
from jaxsimrl.policy import loading
from jaxsimrl.policy.trained import TrainedPolicy


class LoadedPolicy(TrainedPolicy):
    """A trained PPO policy with its env; build it with :func:`load_policy` or :meth:`from_params`."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._rollout_cache: dict[tuple[int, int, bool], Any] = {}  # (steps, episodes, deterministic) -> jit

    def rollout(self, env_params: Any = None, steps: int | None = None, episodes: int = 1, seed: int = 0,
                deterministic: bool = True, **options: Any) -> dict[str, np.ndarray]:
        """Run ``episodes`` episodes for ``steps`` steps (default: a whole episode) in the run's env.

        A pure-JAX env (Lorenz): one jitted scan, see :func:`jaxsimrl.introspect.trajectory.rollout` for
        the record's keys. Another env: its application's rollout, which takes ``options`` (a train-foam
        run: real simpleFoam episodes, ``episodes`` per inlet velocity of ``velocities=`` on ``pool=``
        workers, :func:`jaxsimrl.apps.foam.introspect.rollout.foam_rollout`).
        """
        if self.env is None:
            app = application(self.record.get("env"))
            if app is None or app.rollout is None:
                raise ValueError(f"rollout: no application rolls out env {self.record.get('env')!r}")
            return load(app.rollout)(self, env_params, steps, episodes, seed, deterministic, **options)
        if options:
            raise ValueError(f"rollout: unknown option(s) {', '.join(sorted(options))} for this env "
                             "(they are for an application's rollout)")
        return rollout(self, env_params, steps, episodes, seed, deterministic)


def load_policy(run_dir: str | Path, checkpoint: int | None = None, seed: int = 0,
                agent: int | None = None) -> LoadedPolicy:
    """The policy of ``run_dir``'s last checkpoint (or checkpoint ``checkpoint``, numbered by updates
    done); of a ``--seeds`` run (a batch of agents), that of agent ``agent`` (0-based, required there; see
    :func:`load_agents` for all). Any problem with the run is a one-line ValueError."""
    return loading.load_policy(run_dir, checkpoint, seed, agent, kind=LoadedPolicy)


def load_agents(run_dir: str | Path, checkpoint: int | None = None, seed: int = 0) -> list[LoadedPolicy]:
    """Every agent's policy of a run, read from one checkpoint restore: one for a one-agent run, one per
    seed of a ``--seeds`` run (in agent order)."""
    return loading.load_agents(run_dir, checkpoint, seed, kind=LoadedPolicy)
