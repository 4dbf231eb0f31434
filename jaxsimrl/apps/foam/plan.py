"""train-foam's plan: everything a run is resolved to before anything heavy starts.

The PPOConfig and FoamEnvConfig of a fresh run (train-foam's defaults, then ``--config``, then flags), or
of a resumed one (its config.json, with only ``--episodes``, ``--pool``, ``--backend`` and
``--ray-address`` free), the episode target, the pool and the starting policy of ``--init-from``: a
:class:`FoamPlan`. Bad input is a :class:`jaxsimrl.cli.errors.UsageError` (one line, exit 2), raised
here before a run directory or a worker exists. The run itself is :mod:`jaxsimrl.apps.foam.training`.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

from foam_bridge import (
    MESH_SCALE_USABLE_MIN,
    CaseError,
    FamilyFactory,
    FoamEnvConfig,
    OpenFOAMNotFoundError,
    action_spec,
    validate_pool,
)
from jaxsimrl.agents.ppo.config import PPOConfig
from jaxsimrl.apps.foam.cli.train_family import family_case_dirs, family_configs, family_from_json
from jaxsimrl.apps.foam.config import BUILTIN_ONLY, builtin_only_set, user_case_config
from jaxsimrl.apps.foam.episodes import EPISODES_FILE, EpisodeLog
from jaxsimrl.apps.foam.training import FoamPlan
from jaxsimrl.cli.errors import UsageError, positive_float, positive_int
from jaxsimrl.runs.run_dir import RunDir, read_json

#: Env steps per update, summed over envs: ~20-30 episodes of the paper's 4-8 steps (see foam_ppo_defaults).
FOAM_BATCH = 128
#: The built-in case as the paper's code ran it (a user's --case keeps its own settings instead).
PAPER_CASE = {"simple_variant": "SIMPLEC", "relax_k_omega": 0.8, "inlet_velocity": [35.0, 65.0]}
#: Default reward scale per --reward: each makes a step of the built-in case ~ -0.1 (a SIMPLE iteration
#: costs ~11 linear-solver iterations and, on this project's 2-core machine, 6-25 ms of solver CPU time
#: from mesh 0.5 to the full mesh; experiments/foam/eval-full/eval.csv).
REWARD_SCALES = {"iterations": 1e-3, "linear-iterations": 1e-4, "solver-time": 0.1}
#: FoamEnvConfig's observation switches, each a train-foam flag of its name (off by default: the paper's).
OBSERVE_SWITCHES = (
    ("observe_progress", "observe K / max_iterations, the iterations so far"),
    ("observe_action", "observe the factors in force (the box centre before the first action)"),
    ("observe_gain", "observe the last step's gain: the decades by which the criterion distance fell over "
                     "it (what the last factors earned; for a recurrent policy that probes the case)"),
    ("scale_free_state", "divide the state by the episode's inlet mean |U|^2 instead of 44.2^2, so that "
                         "a slow case looks like a fast one"),
)
#: FoamEnvConfig observation fields with a train-foam flag of the same name.
OBSERVATION_FLAGS = ("residual_features", *(name for name, _ in OBSERVE_SWITCHES))
#: PPOConfig fields with a train-foam flag (the others come from --config).
KNOBS: tuple[tuple[str, Any, str], ...] = (
    ("steps_per_update", positive_int, f"env steps per PPO update over all envs (default {FOAM_BATCH}; "
                                       "rounded up to a multiple of num_minibatches x num_envs)"),
    ("lr", positive_float, "Adam learning rate (paper: 2.5e-4)"),
    ("gamma", float, "discount factor in [0, 1] (paper: 1)"),
    ("gae_lambda", float, "GAE lambda in [0, 1]"),
    ("clip_eps", positive_float, "PPO clipping epsilon"),
    ("ent_coef", float, "entropy bonus coefficient (>= 0), on the squashed policy's entropy"),
    ("update_epochs", positive_int, "SGD epochs over each update's batch"),
    ("num_minibatches", positive_int, "minibatches per epoch"),
    ("reward_scale", positive_float, "rewards (minus the --reward cost) are multiplied by this before GAE "
                                     "(default: 1e-3 for iterations, 1e-4 for linear-iterations, 0.1 for "
                                     "solver-time)"),
    ("action_margin", float, "the tanh squash maps onto the action box widened by this fraction of its "
                             "width on each side, then clips into the box, so the bounds are reachable "
                             "(default 0: plain tanh, bounds only approached)"),
)


#: PPOConfig fields that prepare the network's input: a starting policy (--init-from) keeps its source's.
INPUT_HANDLING = ("normalize_obs", "obs_clip", "obs_std_floor")
#: How the network's output becomes an action: --init-from carries it unless this run sets it.
ACTION_MAPPING = ("action_margin",)


def foam_ppo_defaults(num_envs: int, reward: str = "iterations") -> dict[str, Any]:
    """The PPOConfig fields train-foam sets before --config and flags.

    The paper's network and optimiser (2 x 64 tanh MLP, lr 2.5e-4, gamma 1). Batch sizes: the paper's code
    trained on 200-step batches with minibatches of 128 (RLlib); its episodes last 4-8 steps (400-800
    iterations / 100), so a batch of ~128 steps holds 20-30 whole episodes, enough for a return estimate
    with gamma = 1, while an update still comes every few minutes on 2 cores. 4 minibatches x 10 epochs
    gives 40 SGD steps per update, as RLlib's 30 passes over 1.5 minibatches did. The MLP needs no
    sequence: seq_len 1. Rewards are -100 per step and down to -max_iterations on a failure: a reward
    scale of 1e-3 keeps returns (and so the value targets) O(1) (-0.4 to -4); the other rewards' scales
    (REWARD_SCALES) do the same for their units.
    """
    per_env = max(4, math.ceil(FOAM_BATCH / num_envs))
    per_env += -per_env % 4
    return {"num_envs": num_envs, "steps_per_update": per_env * num_envs, "network": "mlp",
            "hidden_sizes": [64, 64], "activation": "tanh", "lr": 2.5e-4, "gamma": 1.0, "gae_lambda": 0.95,
            "update_epochs": 10, "num_minibatches": 4, "seq_len": 1, "reward_scale": REWARD_SCALES[reward],
            "updates_per_chunk": 1, "ent_coef": 0.0}


def episode_steps_bound(foam: Any) -> int:
    """The most env steps one episode can take: every step runs ``interval`` SIMPLE iterations (a failed
    convergence check goes on within its step) and the cap ends the episode at ``max_iterations``; one
    spare step, so that the bound never rests on the exact step accounting."""
    return math.ceil(foam.max_iterations / foam.interval) + 1


def total_steps_for(episodes: int, steps_per_update: int, num_envs: int, foam: Any,
                    updates_done: int = 0) -> int:
    """PPOConfig.total_steps of a train-foam run: ``updates_done`` updates plus enough whole updates for
    ``episodes`` more episodes to end, whatever they do (each env ends one at least every
    :func:`episode_steps_bound` steps). Only a safety bound: the run stops after the update in which
    the episode target is reached, so the bound never shortens a run."""
    per_env = math.ceil(max(episodes, 0) / num_envs) * episode_steps_bound(foam)
    updates = math.ceil(per_env / (steps_per_update // num_envs))
    return max(updates_done + updates, 1) * steps_per_update


def _check_no_anneal(ppo: Any) -> None:
    if ppo.anneal_lr:
        raise UsageError("invalid config: anneal_lr is not available in train-foam: its length is a number "
                         "of episodes, whose env steps are not known in advance, so a decay over env steps "
                         "would not end at the episode target")



# ---- the plan: everything resolved before anything heavy starts (a jaxsimrl.apps.foam.training.FoamPlan)
# ----
def fresh_plan(args: argparse.Namespace) -> FoamPlan:
    extra = _read_config(args.config) if args.config else {}
    num_envs = args.num_envs or args.pool or 2
    episodes = args.episodes or 2000
    flags = {name: getattr(args, name) for name, _, _ in KNOBS if getattr(args, name) is not None}
    if args.init_action is not None:
        flags["init_action"] = tuple(args.init_action)
    if getattr(args, "async_envs", None) is not None:
        flags["async_envs"] = args.async_envs
    family = _family(args, extra.get("foam", {}))
    try:
        foam = _foam_config(args, extra.get("foam", {})) if not family else \
            max(family.values(), key=lambda cfg: cfg.max_iterations)  # the shapes; the longest budget
        ppo_values = {**foam_ppo_defaults(num_envs, foam.reward), **extra.get("ppo", {}), **flags}
        ppo_values["steps_per_update"] += -ppo_values["steps_per_update"] % (ppo_values["num_minibatches"]
                                                                             * num_envs)
        # the episode target governs the run's length (a total_steps of --config is overridden)
        ppo_values["total_steps"] = total_steps_for(episodes, ppo_values["steps_per_update"], num_envs, foam)
        ppo = PPOConfig.from_dict(ppo_values)
        _check_init_action(ppo, foam)
        pool = _pool(ppo, args.pool)
    except (TypeError, ValueError) as err:
        raise UsageError(f"invalid config: {err}") from None
    if ppo.updates_per_chunk != 1:
        raise UsageError("invalid config: updates_per_chunk must be 1 for train-foam (a checkpoint after "
                         "every update)")
    _check_no_anneal(ppo)
    _check_ray_address(args.backend or "local", args.ray_address)
    out = Path(args.out) if args.out else Path("runs") / time.strftime("foam-%Y%m%d-%H%M%S", time.gmtime())
    try:
        RunDir.check_new(out)
    except ValueError as err:
        raise UsageError(str(err)) from None
    init_from = None
    if args.init_from:
        init_from = _starting_policy(args.init_from, ppo, foam)
        ppo = _carry_policy_settings(init_from, ppo, given=set(extra.get("ppo", {})) | set(flags))
    return FoamPlan(ppo, foam, episodes, 0 if args.seed is None else args.seed, pool,
                    args.backend or "local", args.ray_address, out, resume=False, init_from=init_from,
                    **_family_setup(family))


def _family(args: argparse.Namespace, extra: dict[str, Any]) -> dict[str, Any]:
    """--family's cases and their configs (jaxsimrl.apps.foam.cli.train_family), measured now; {} without
    it."""
    if not getattr(args, "family", None):
        return {}

    given = [f"--{name.replace('_', '-')}" for name in ("case", "mesh_scale", "step_height", "relax_k_omega")
             if getattr(args, name, None) is not None]
    if given:
        raise UsageError(f"{given[0]} does not go with --family (each case keeps its own mesh and settings; "
                         f"the family acts on U, p and the turbulence)")
    try:
        template = _foam_template(args, extra)
        return family_configs(family_case_dirs(args.family), template,
                              lambda text: sys.stderr.write(f"jaxsimrl train-foam: {text}\n"))
    except (CaseError, OpenFOAMNotFoundError, ValueError) as err:
        raise UsageError(" ".join(str(err).split())) from None


def _foam_template(args: argparse.Namespace, extra: dict[str, Any]) -> Any:
    """A family's shared settings: the defaults, --config's "foam" section, the observation flags."""
    values = {**FoamEnvConfig().to_json(), **extra, "work_dir": None}
    values.update({name: value for name, value in _shared_flags(args).items() if value is not None})
    return FoamEnvConfig.from_json(values)


def _shared_flags(args: argparse.Namespace) -> dict[str, Any]:
    """FoamEnvConfig fields from the flags a single case and a family take alike (None: not given)."""
    return {"max_iterations": args.max_iterations, "reward": args.reward,
            "confirm_alpha_u": args.confirm_alpha_u,
            **{name: getattr(args, name) for name in OBSERVATION_FLAGS}}


def _family_setup(family: dict[str, Any]) -> dict[str, Any]:
    """FoamPlan's family fields: the configs, and the factory every worker builds its envs with."""
    if not family:
        return {}

    return {"family": family, "make_env": FamilyFactory(family)}


def _pool(ppo: Any, pool: int | None) -> int:
    """The pool size: at most one worker per env (all async_envs of an asynchronous batch); by default
    one per env of the learner's batch (num_envs), up to the CPU count."""
    if pool is None:
        return validate_pool(ppo.num_envs)
    return validate_pool(ppo.async_envs or ppo.num_envs, pool)


def _check_async_envs(asked: int | None, ppo: Any, run: Path) -> None:
    """--async-envs on --resume: only the run's own (the batch's shape is part of its checkpoints)."""
    if asked is not None and asked != ppo.async_envs:
        raise UsageError(f"--async-envs {asked} differs from {run}'s ({ppo.async_envs}): a resumed run keeps "
                         f"its batch")


def _check_ray_address(backend: str, address: str | None, run: Path | None = None) -> None:
    """--ray-address only with the ray backend, on fresh runs and on resume alike."""
    if address and backend != "ray":
        ran = f" ({run} ran on the {backend} backend: add --backend ray to move it)" if run else ""
        raise UsageError(f"--ray-address needs --backend ray{ran}")


def _check_init_action(ppo: Any, foam: Any) -> None:
    """ValueError unless ``ppo.init_action`` (if set) has one factor per action, each in the env's box."""
    import numpy as np

    action = ppo.init_action
    if action is None:
        return
    if len(action) != foam.action_size:
        raise ValueError(f"init_action: expected {foam.action_size} factors, got {len(action)}")
    box = action_spec(foam)  # shares of each case's box with action_share
    low, high = (np.asarray(bound, np.float64).tolist() for bound in (box.low, box.high))
    if any(not lo <= a <= hi for a, lo, hi in zip(action, low, high, strict=True)):
        raise ValueError(f"init_action: {list(action)} is outside the action box [{low}, {high}]")


def _carry_policy_settings(policy: Any, ppo: Any, given: set[str]) -> Any:
    """This run's PPOConfig with the --init-from source's input handling and action mapping, so that the
    starting policy acts as its source did. An action mapping that this run sets (``given``) is kept: a
    plain-tanh policy mapped onto a widened box (--action-margin) is a documented use. Input handling
    set differently is refused: the network was trained on inputs prepared the source's way."""
    theirs = policy.config
    differ = [name for name in INPUT_HANDLING + ACTION_MAPPING if getattr(theirs, name) != getattr(ppo, name)]
    refused = [name for name in differ if name in INPUT_HANDLING and name in given]
    if refused:
        name = refused[0]
        raise UsageError(f"--init-from: {policy.run_dir} was trained with {name} {getattr(theirs, name)!r}, "
                         f"this run sets {getattr(ppo, name)!r}: its network expects inputs prepared the "
                         f"source's way (leave {name} out to carry it)")
    carried = {name: getattr(theirs, name) for name in differ if name not in given}
    for name in differ:
        what = ("this run carries it" if name in carried else
                f"this run uses {getattr(ppo, name)!r} as given: its first actions differ from the source's")
        sys.stderr.write(f"jaxsimrl train-foam: --init-from: {policy.run_dir} has {name} "
                         f"{getattr(theirs, name)!r}; {what}\n")
    return type(ppo).from_dict({**ppo.to_dict(), **carried}) if carried else ppo


def _starting_policy(run_dir: str, ppo: Any, foam: Any, checkpoint: int | None = None) -> Any:
    """The policy of ``--init-from`` (its last checkpoint, or ``checkpoint``), checked to fit this run's
    network, observation and action box."""
    import numpy as np

    from jaxsimrl.policy import load_policy

    try:
        policy = load_policy(run_dir, checkpoint)
    except ValueError as err:
        raise UsageError(f"--init-from: {err}") from None
    if policy.record.get("env") != "foam":
        raise UsageError(f"--init-from: {run_dir} is not a train-foam run")
    mine = (ppo.network, tuple(ppo.hidden_sizes), ppo.activation, foam.observation_size)
    trained = policy.config
    theirs = (trained.network, tuple(trained.hidden_sizes), trained.activation, policy.obs_dim)
    if mine != theirs:
        raise UsageError(f"--init-from: {run_dir} has (network, hidden sizes, activation, observation size) "
                         f"{theirs}, this run {mine}")
    spec = action_spec(foam)  # shares of each case's box with action_share
    box = (spec.low.tolist(), spec.high.tolist())
    same_size = len(policy.action_low) == len(box[0])  # 2 factors, or 3 with the k/omega action
    if not (same_size and np.allclose(policy.action_low, box[0]) and np.allclose(policy.action_high, box[1])):
        raise UsageError(f"--init-from: {run_dir} acts in the box {policy.action_low.tolist()}-"
                         f"{policy.action_high.tolist()}, this run in {box[0]}-{box[1]}")
    return policy


def _foam_config(args: argparse.Namespace, extra: dict[str, Any]) -> Any:
    """The FoamEnvConfig: the paper's built-in case, then --config's "foam" section, then flags."""
    if extra.get("work_dir") is not None:
        raise UsageError('--config: "foam": work_dir is not used by train-foam: every worker builds its '
                         "cases in a temporary directory of its own (set TMPDIR to move them)")
    if args.mesh_scale is not None and args.mesh_scale < MESH_SCALE_USABLE_MIN:
        raise UsageError(f"--mesh-scale {args.mesh_scale:g} is below {MESH_SCALE_USABLE_MIN:g}: coarser "
                         f"meshes are a different control problem (many episodes diverge)")
    values = {**FoamEnvConfig().to_json(), **extra}
    flags = {"mesh_scale": args.mesh_scale, "step_height": _step_height(args.step_height),
             "case_dir": args.case, "relax_k_omega": args.relax_k_omega, **_shared_flags(args)}
    values.update({name: value for name, value in flags.items() if value is not None})
    if values.get("case_dir") is None:  # the built-in case: its paper defaults, written out in config.json
        for name, value in PAPER_CASE.items():
            values[name] = value if values.get(name) is None else values[name]
    if values.get("case_dir") is not None:
        values["case_dir"] = str(Path(values["case_dir"]).resolve())
    values["work_dir"] = None  # cases live in a temporary directory per process, never in the run dir
    cfg = FoamEnvConfig.from_json(values)
    return cfg if cfg.builtin else _user_case(cfg, args, extra)


def _step_height(values: list[float] | None) -> float | list[float] | None:
    """--step-height: one height, or LOW HIGH (a range drawn per episode)."""
    if values is None or len(values) == 1:
        return None if values is None else values[0]
    if len(values) != 2 or values[0] > values[1]:
        raise UsageError(f"--step-height: expected one height or LOW HIGH with LOW <= HIGH, got "
                         f"{' '.join(f'{v:g}' for v in values)}")
    return list(values)


def _user_case(cfg: Any, args: argparse.Namespace, extra: dict[str, Any]) -> Any:
    """A user's case: built-in-geometry settings refused; the case's own convergence criterion and action
    box where --config's "foam" section does not set them (jaxsimrl.apps.foam.config.user_case_config)."""
    flags = [f"--{name.replace('_', '-')}" for name in BUILTIN_ONLY if getattr(args, name) is not None]
    given = flags or [f'--config "foam": {name}' for name in builtin_only_set(extra)]
    if given:
        raise UsageError(f"{given[0]} applies to the built-in backward-facing step only, not to --case "
                         f"(a case of your own keeps its own mesh)")
    try:
        return user_case_config(cfg, explicit=extra)
    except (CaseError, OpenFOAMNotFoundError) as err:
        raise UsageError(str(err)) from None


def resume_plan(args: argparse.Namespace) -> FoamPlan:
    fixed = ["config", "num_envs", "mesh_scale", "step_height", "max_iterations", "case", "family", "reward",
             "seed",
             "out", "init_from", "init_action", "confirm_alpha_u", "relax_k_omega", *OBSERVATION_FLAGS]
    changed = [name for name in fixed + [k for k, _, _ in KNOBS] if getattr(args, name) is not None]
    if changed:
        flag = "--" + changed[0].replace("_", "-")
        raise UsageError(f"{flag} cannot be used with --resume: a resumed run keeps "
                         f"its saved config (only --episodes, --pool, --backend, --ray-address)")
    try:
        run = RunDir.existing(args.resume)
        record = run.read_config()
        if record.get("env") != "foam":
            raise ValueError(f"{run.path} is not a train-foam run (env {record.get('env')!r})")
        ppo = PPOConfig.from_dict(record["ppo"])
        foam = FoamEnvConfig.from_json(record["foam"])
        pool = _pool(ppo, args.pool or record.get("pool"))
    except (KeyError, TypeError, ValueError) as err:
        raise UsageError(f"cannot resume: {err}") from None
    _check_async_envs(getattr(args, "async_envs", None), ppo, run.path)
    _check_no_anneal(ppo)
    backend = args.backend or record.get("backend", "local")
    _check_ray_address(backend, args.ray_address, run.path)
    episodes = int(record.get("episodes_target", 2000))
    if args.episodes is not None:
        if args.episodes < episodes:
            raise UsageError(f"--episodes {args.episodes} is below the run's {episodes}: it may only be "
                             f"raised")
        episodes = args.episodes
    steps = run.checkpoint_steps()
    # Killed before its first checkpoint: start over from config.json (the rows it wrote are dropped).
    done = steps[-1] if steps else 0
    ended = len(EpisodeLog.load(run.path / EPISODES_FILE, done).rows)
    ppo = ppo.with_total_steps(total_steps_for(episodes - ended, ppo.steps_per_update, ppo.num_envs, foam,
                                               updates_done=done))
    init_from = None
    if not steps and record.get("init_from"):  # the same starting network as the first time
        source = record["init_from"]
        init_from = _starting_policy(source["run_dir"], ppo, foam, checkpoint=source.get("update"))

    return FoamPlan(ppo, foam, episodes, int(record.get("seed", 0)), pool, backend, args.ray_address,
                    run.path, resume=True, record=record, init_from=init_from,
                    **_family_setup(family_from_json(record)))


def _read_config(path: str) -> dict[str, Any]:
    try:
        values = read_json(path)
    except ValueError as err:
        raise UsageError(f"--config: {err}") from None
    if not isinstance(values, dict) or set(values) - {"ppo", "foam"}:
        raise UsageError(f'--config {path} must hold a JSON object with "ppo" and/or "foam" sections')
    for name in ("ppo", "foam"):
        if not isinstance(values.get(name, {}), dict):
            raise UsageError(f'--config {path}: "{name}" must be a JSON object')
    return values
