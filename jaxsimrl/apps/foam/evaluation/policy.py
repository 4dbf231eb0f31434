"""A train-foam run's policy, loaded for evaluation.

:func:`load_foam_run` reads ``RUN_DIR/config.json`` (``{"env": "foam", "seed", "ppo", "foam"}``) and the
last checkpoint through :func:`jaxsimrl.policy.load_policy` (the acting part of the RunnerState: ``params``
and ``normalizer``). The learned controllers act with it through a :class:`jaxsimrl.policy.BatchActor`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from foam_bridge import FoamEnvConfig
from jaxsimrl.agents.ppo.config import PPOConfig
from jaxsimrl.agents.ppo.policy import PolicyParams
from jaxsimrl.policy import TrainedPolicy, load_policy
from jaxsimrl.runs.run_dir import RunDir


@dataclass(frozen=True)
class FoamRun:
    """What evaluation needs of a train-foam run: its directory, its policy and its training seed."""

    path: Path
    policy: TrainedPolicy
    seed: int

    @property
    def config(self) -> PPOConfig:
        return self.policy.config

    @property
    def foam(self) -> FoamEnvConfig:
        """The FoamEnvConfig the run trained with (its action box is the policy's)."""
        return self.policy.env_params

    @property
    def params(self) -> PolicyParams:
        return self.policy.params

    @property
    def checkpoint_step(self) -> int | None:
        return self.policy.checkpoint

    @property
    def update(self) -> int:
        return self.policy.update


def load_foam_run(path: str | Path) -> FoamRun:
    """The config and last checkpoint of a train-foam run directory; one-line ValueError if it is not one."""
    run = RunDir.existing(path)
    record = run.read_config()
    if record.get("env") != "foam" or not isinstance(record.get("foam"), dict):
        raise ValueError(f"{run.path} is not a train-foam run (its config.json has env "
                         f"{record.get('env')!r}; eval-foam needs env 'foam' and a 'foam' section)")
    return FoamRun(run.path, load_policy(run.path), int(record.get("seed", 0)))
