"""PPO hyper-parameters as one frozen, typed, validated dataclass.

Defaults reproduce the paper's Lorenz setup (Pawar & Maulik, section 3.1): 2 workers (parallel envs),
8000 env steps per update, 2e5 steps in total, 2 x 64 tanh layers followed by an LSTM of 256 cells,
Adam at 2.5e-4. Fields the paper does not fix (gamma, lambda, epochs, ...) are tuned for this task; see
benchmarks/RESULTS_ppo.md for what was tried.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

NETWORKS = ("lstm", "mlp")
ACTIVATIONS = ("tanh", "relu")


#: Fields whose value may differ between the agents of one batch (scalars the update computes with, not
#: shapes): ``hparams`` of :class:`jaxsimrl.agents.ppo.batch.SeedBatch`, ``--sweep`` of train-lorenz.
SWEEPABLE = ("lr", "ent_coef", "clip_eps", "gamma", "gae_lambda", "vf_coef")


@dataclass(frozen=True)
class PPOConfig:
    """Everything that defines one PPO training run (besides the env and the seed)."""

    num_envs: int = 2  # the paper's "workers"
    steps_per_update: int = 8000  # split evenly: each env runs steps_per_update // num_envs steps
    total_steps: int = 200_000
    network: str = "lstm"
    hidden_sizes: tuple[int, ...] = (64, 64)
    lstm_size: int = 256
    activation: str = "tanh"
    lr: float = 2.5e-4
    anneal_lr: bool = False  # linear decay to 0 at the last update
    # Where the linear decay starts: update anneal_start_update at rate anneal_start_lr (None = lr).
    # Fresh runs decay from lr at update 0. Raising total_steps on resume keeps the anchor and moves the
    # decay's end (see with_total_steps). Runs of older versions were re-anchored at the resume point.
    anneal_start_update: int = 0
    anneal_start_lr: float | None = None
    max_grad_norm: float = 0.5
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_eps: float = 0.2
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    clip_value: bool = False  # PPO2-style clipped value loss
    normalize_advantages: bool = True
    update_epochs: int = 4
    num_minibatches: int = 4
    seq_len: int = 50  # steps per training chunk (LSTM truncated backprop length)
    normalize_obs: bool = True
    obs_clip: float = 10.0  # normalised observations are clipped to +-obs_clip
    # Lower bound of the std the normaliser divides by: a feature that is (nearly) constant in the
    # statistics, e.g. at reset, must not be blown up to +-obs_clip by its first change.
    obs_std_floor: float = 0.01
    reward_scale: float = 0.01  # rewards are multiplied by this before GAE (keeps values O(1))
    init_log_std: float = -0.5  # initial log std of the pre-squash Gaussian
    # The tanh squash maps onto the action box widened by this fraction of its width on each side, and
    # actions are clipped into the box: 0 = plain tanh (bounds approached, never reached).
    action_margin: float = 0.0
    # The action the initial policy's mean maps to (one entry per action; None: the box centre). A
    # solver controller can start from a known good constant and learn where to leave it.
    init_action: tuple[float, ...] | None = None
    updates_per_chunk: int = 5  # updates per jitted run_chunk call (progress / checkpoint granularity)
    # Envs behind an asynchronous host batch (EnvPool-style: each learner step takes the num_envs envs
    # that are ready first, out of async_envs > num_envs); None = lock-step, every env every step.
    # MLP network only: a recurrent carry would need each env's steps as one sequence.
    async_envs: int | None = None

    # ---- derived sizes -------------------------------------------------------------------------
    @property
    def steps_per_env(self) -> int:
        """Env steps each parallel env runs per update."""
        return self.steps_per_update // self.num_envs

    @property
    def num_updates(self) -> int:
        return self.total_steps // self.steps_per_update

    @property
    def chunks_per_env(self) -> int:
        """Training sequences of length seq_len cut from each env's rollout."""
        return self.steps_per_env // self.seq_len

    def learning_rate(self, update: float) -> float:
        """The rate used in update ``update`` (0-based, fractions allowed: SGD steps within it)."""
        if not self.anneal_lr:
            return self.lr
        start = self.lr if self.anneal_start_lr is None else self.anneal_start_lr
        span = max(self.num_updates - self.anneal_start_update, 1)
        return start * min(max(1.0 - (update - self.anneal_start_update) / span, 0.0), 1.0)

    def with_total_steps(self, total_steps: int) -> PPOConfig:
        """This config trained further, to ``total_steps``. An annealed rate then follows the decay of a
        run planned for ``total_steps`` from its anchor: from the resume point it is the rate that run
        would have there, so extending a finished run (whose rate reached 0) trains at a rate > 0. (It
        jumps up from the old decay's: continuing that one from 0, or nearly 0, would not learn.)"""
        return PPOConfig.from_dict({**self.to_dict(), "total_steps": total_steps})

    # ---- validation / serialisation ------------------------------------------------------------
    def validate(self) -> PPOConfig:
        """Raise ValueError with a one-line message naming the first bad field; return self."""
        for names, ok, what in _FIELD_RULES:
            for name in names:
                value = getattr(self, name)
                if not ok(value):
                    raise ValueError(f"{name} must be {what}, got {value!r}")
        self._validate_divisibility()
        self._validate_async()
        if self.anneal_start_lr is not None and not (_is_number(self.anneal_start_lr)
                                                     and 0 <= self.anneal_start_lr < _INF):
            raise ValueError(f"anneal_start_lr must be null or a non-negative number, got "
                             f"{self.anneal_start_lr!r}")
        return self

    def _validate_divisibility(self) -> None:
        if self.steps_per_update % self.num_envs:
            raise ValueError(f"steps_per_update ({self.steps_per_update}) must be divisible by "
                             f"num_envs ({self.num_envs})")
        if self.total_steps < self.steps_per_update:
            raise ValueError(f"total_steps ({self.total_steps}) must be >= steps_per_update "
                             f"({self.steps_per_update})")
        if self.steps_per_env % self.seq_len:
            raise ValueError(f"seq_len ({self.seq_len}) must divide the steps per env per update "
                             f"({self.steps_per_env})")
        if self.chunks_per_env % self.num_minibatches:
            raise ValueError(f"num_minibatches ({self.num_minibatches}) must divide the chunks per env "
                             f"({self.chunks_per_env} = {self.steps_per_env} steps / seq_len {self.seq_len})")

    def _validate_async(self) -> None:
        if self.async_envs is None:
            return
        if not _is_int(self.async_envs) or self.async_envs <= self.num_envs:
            raise ValueError(f"async_envs must be null or an integer > num_envs ({self.num_envs}), got "
                             f"{self.async_envs!r}")
        if self.network != "mlp":
            raise ValueError(f"async_envs needs network \"mlp\" (a recurrent network's carry follows one "
                             f"env's steps), got {self.network!r}")

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (tuples become lists)."""
        out = dataclasses.asdict(self)
        out["hidden_sizes"] = list(self.hidden_sizes)
        out["init_action"] = None if self.init_action is None else list(self.init_action)
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PPOConfig:
        """Build and validate a config; unknown keys raise ValueError naming them."""
        if not isinstance(data, dict):
            raise ValueError(f"a PPO config must be a JSON object, got {type(data).__name__}")
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"unknown PPO config key(s): {', '.join(unknown)}")
        values = dict(data)
        if "hidden_sizes" in values:
            sizes = values["hidden_sizes"]
            if not isinstance(sizes, list | tuple):
                raise ValueError(f"hidden_sizes must be a list of positive ints, got {sizes!r}")
            values["hidden_sizes"] = tuple(sizes)
        if isinstance(values.get("init_action"), list):
            values["init_action"] = tuple(values["init_action"])
        return cls(**values).validate()


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


_INF = float("inf")
# (fields, test, what the message says they must be), checked in this order
_FIELD_RULES: tuple[tuple[tuple[str, ...], Callable[[Any], bool], str], ...] = (
    (("num_envs", "steps_per_update", "total_steps", "lstm_size", "update_epochs", "num_minibatches",
      "seq_len", "updates_per_chunk"), lambda v: _is_int(v) and v > 0, "a positive integer"),
    (("anneal_start_update",), lambda v: _is_int(v) and v >= 0, "a non-negative integer"),
    (("lr", "max_grad_norm", "clip_eps", "obs_clip", "reward_scale"),
     lambda v: _is_number(v) and 0 < v < _INF, "a positive number"),
    (("gamma", "gae_lambda"), lambda v: _is_number(v) and 0 <= v <= 1, "a number in [0, 1]"),
    (("ent_coef", "vf_coef", "obs_std_floor"), lambda v: _is_number(v) and 0 <= v < _INF,
     "a non-negative number"),
    (("network",), lambda v: v in NETWORKS, f"one of {NETWORKS}"),
    (("activation",), lambda v: v in ACTIVATIONS, f"one of {ACTIVATIONS}"),
    (("hidden_sizes",), lambda v: isinstance(v, tuple | list) and bool(v)
     and all(_is_int(h) and h > 0 for h in v), "a non-empty list of positive ints"),
    (("init_log_std",), lambda v: _is_number(v) and -10 <= v <= 2, "a number in [-10, 2]"),
    (("action_margin",), lambda v: _is_number(v) and 0 <= v <= 0.5, "a number in [0, 0.5]"),
    (("init_action",), lambda v: v is None or (isinstance(v, tuple | list) and bool(v)
                                               and all(_is_number(a) for a in v)),
     "null or a list of numbers"),
    (("anneal_lr", "clip_value", "normalize_advantages", "normalize_obs"), lambda v: isinstance(v, bool),
     "true or false"),
)
