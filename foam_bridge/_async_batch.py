"""AsyncFoamEnv: more foam envs than the learner takes at once; each call returns whichever are ready.

EnvPool's asynchronous mode on the foam bridge's pool (opt-in; BatchedFoamEnv's lock-step stays the
default):

    env = AsyncFoamEnv(cfg, num_envs=4, batch_size=2, pool=2, seed=0)
    env.async_reset()                                        # every env starts an episode (blocks)
    while True:
        ids, obs, reward, terminated, truncated, infos = env.recv()   # the first batch_size ready envs
        env.send(policy(obs), ids)                                    # step them; returns at once

``recv()`` blocks until ``batch_size`` envs are ready and returns them in the order they became ready:
row ``r`` is env ``ids[r]``; ``reward``/``terminated``/``truncated`` are those of the env's last step
(0/False/False right after ``async_reset``), and ``infos`` is batched over the rows the gymnasium way,
as BatchedFoamEnv's (``infos[key][r]``, ``infos["_" + key][r]``). ``send(actions, ids)`` steps exactly
the envs the last ``recv`` returned (in any order). A worker hosts several envs and serves them in
turn, so with ``num_envs`` > ``pool`` a worker always has a step queued while the learner chooses the
actions of the others: no env waits for the slowest one, and none waits for a barrier.

Episode ends follow BatchedFoamEnv's "same step" auto-reset, in the background: an env whose episode
ended is reset at once, by its worker, while the others step; it becomes ready when its reset is back,
with ``obs`` the new episode's first observation, ``infos["final_obs"]``/``infos["final_info"]`` the
ended one's. Faults are BatchedFoamEnv's, with its code (foam_bridge._batched.FoamBatchCore): a dead or
hung worker ends its envs' episodes with outcome "crashed", its cause and the failure penalty, and is
replaced; a reset that fails (a worker death gets one more try) leaves the env with the ended episode's
last observation and its reset retried when it is next sent: a retry that succeeds is a non-transition
(reward 0, ``truncated``, ``final_obs`` that observation, no ``final_info``), one that fails a failed
episode of 0 iterations with cause "reset failed: ...". ``recv`` and ``send`` never raise for a solver
or worker fault; they raise ValueError for a caller's error (bad actions or ids, recv before send).
``async_reset`` raises as ``BatchedFoamEnv.reset`` does when an env cannot start at all.

Resuming: :meth:`AsyncFoamEnv.snapshot` records, per env, its running episode (reset seed, the actions
whose results were absorbed, K, return, observation; foam_bridge._replay), its seed stream and where it
stands: with the learner, a step in flight (its action), a background reset in flight (its seed and the
ended step's result, or the action of a retried reset), or a result waiting for ``recv`` (JSON-ready);
an env whose reset failed keeps its cause and last observation. :meth:`AsyncFoamEnv.replay` rebuilds
all of it in another batch: it replays the running episodes (reset, step, check: the solver is
deterministic), puts the waiting results back in their order and the learner's envs back with the
learner, and sends the steps and resets that were in flight again without waiting for them. So a
learner restored from the same moment goes on as if never stopped, except for the order in which the
re-sent envs become ready: that depends on the workers' timing, as it does in any asynchronous batch.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

import numpy as np

from foam_bridge._backends import Reply, Request
from foam_bridge._batched import FoamBatchCore, _InfoBatcher, _reset_cause, _reset_error, _Tally
from foam_bridge._config import ACTION_NAMES, FoamEnvConfig
from foam_bridge._replay import from_json, json_ready

__all__ = ["AsyncFoamEnv"]

#: How long recv waits on the pool per poll (it polls until enough envs are ready; deadlines still hold).
POLL_S = 1.0


class _Ready:
    """One env's result waiting for the learner: its row of recv's arrays and the infos for that row."""

    def __init__(self, obs: np.ndarray, reward: float = 0.0, terminated: bool = False,
                 truncated: bool = False, infos: list[dict[str, Any]] | None = None) -> None:
        self.obs, self.reward, self.terminated, self.truncated = obs, reward, terminated, truncated
        self.infos = infos or []

    def to_json(self) -> dict[str, Any]:
        """JSON-ready (a snapshot's); :meth:`from_json` makes it a _Ready again."""
        return {"obs": json_ready(self.obs), "reward": float(self.reward),
                "terminated": bool(self.terminated), "truncated": bool(self.truncated),
                "infos": json_ready(self.infos)}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> _Ready:
        return cls(np.asarray(data["obs"], np.float32), data["reward"], data["terminated"], data["truncated"],
                   [from_json(info) for info in data["infos"]])


class AsyncFoamEnv(FoamBatchCore):
    """``num_envs`` foam envs on ``pool`` workers, ``batch_size`` per recv/send (see the module docstring).
    The other arguments are BatchedFoamEnv's (``make_env``: foam_bridge._standin)."""

    def __init__(self, cfg: FoamEnvConfig, num_envs: int, batch_size: int | None = None,
                 **batch_args: Any) -> None:
        super().__init__(cfg, num_envs, **batch_args)
        pool = self.backend.pool
        self.batch_size = pool if batch_size is None else batch_size
        if isinstance(self.batch_size, bool) or not isinstance(self.batch_size, int) \
                or not 1 <= self.batch_size <= num_envs:
            self.close()
            raise ValueError(f"batch_size must be an integer in [1, num_envs={num_envs}], got {batch_size!r}")
        self._rows = _InfoBatcher(self.batch_size)
        self._ready: OrderedDict[int, _Ready] = OrderedDict()  # env -> result, in the order they came
        self._with_learner: set[int] = set()  # returned by recv, not sent back yet
        self._in_flight: dict[int, tuple[str, Any]] = {}  # env -> (what, context) of its request
        self._retried: set[int] = set()  # envs whose reset already had its one retry after a worker death

    # ----- the learner's side ------------------------------------------------------------------
    def async_reset(self, seed: int | list[int] | None = None, options: dict[str, Any] | None = None) -> None:
        """A new episode in every env (blocks until all have started); ``seed`` re-seeds the streams."""
        if self._in_flight or self._ready or self._with_learner:
            self._drain()
        if seed is not None:
            self._streams = self._seed_streams(seed)
        results, failures = self._reset_envs(list(range(self.num_envs)), options)
        if failures:
            raise _reset_error(failures[min(failures)])
        for env_id in range(self.num_envs):
            obs, info = results[env_id]
            self._ready[env_id] = _Ready(obs, infos=[info])

    def recv(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """The first ``batch_size`` envs that are ready: (ids, obs, reward, terminated, truncated, infos)."""
        if self._with_learner:
            raise ValueError(f"recv: send() the actions of env(s) {sorted(self._with_learner)} first")
        while len(self._ready) < self.batch_size:
            if not self._in_flight:
                raise ValueError(f"recv: {len(self._ready)} env(s) can be ready, batch_size is "
                                 f"{self.batch_size}; call async_reset() first")
            self._absorb(self.backend.collect(POLL_S))
        ids = list(self._ready)[:self.batch_size]
        results = [self._ready.pop(env_id) for env_id in ids]
        self._with_learner = set(ids)
        infos: dict[str, Any] = {}
        for row, result in enumerate(results):
            for info in result.infos:
                infos = self._rows.add(infos, info, row)
        return (np.asarray(ids, np.int32), np.stack([r.obs for r in results]).astype(np.float32),
                np.array([r.reward for r in results], np.float64), np.array([r.terminated for r in results]),
                np.array([r.truncated for r in results]), infos)

    def send(self, actions: Any, env_ids: Any) -> None:
        """Step the envs ``env_ids`` (those the last recv returned) with ``actions`` [len(ids), 2 or 3]."""
        ids = [int(i) for i in np.asarray(env_ids).reshape(-1)]
        actions = np.asarray(actions, np.float64)
        size = self.cfg.action_size
        if sorted(ids) != sorted(self._with_learner):
            raise ValueError(f"send: expected the env ids the last recv returned, "
                             f"{sorted(self._with_learner)}, got {ids}")
        if actions.shape != (len(ids), size):
            raise ValueError(f"actions: expected shape ({len(ids)}, {size}), got {actions.shape}")
        if not np.isfinite(actions).all():
            raise ValueError(f"actions: expected finite ({', '.join(ACTION_NAMES[:size])}), "
                             f"got {actions.tolist()}")
        self._with_learner.clear()
        requests = []
        for env_id, action in zip(ids, actions, strict=True):
            if self._tallies[env_id].reset_failure:  # no episode to step: retry its reset
                requests.append(self._sent_reset(env_id, ("retry", action)))
            elif (lost := self._stranded(env_id)) is not None:  # it ends as if the step had been sent
                requests += self._stepped(lost, action)
            else:
                requests.append(self._sent_step(env_id, action))
        self.backend.submit(requests)

    # ----- the pool's side ---------------------------------------------------------------------
    def _sent_step(self, env_id: int, action: np.ndarray) -> Request:
        """A step of ``env_id`` (FoamBatchCore's request), in flight."""
        self._in_flight[env_id] = ("step", action)
        return self._step_request(env_id, action)

    def _sent_reset(self, env_id: int, context: Any, seed: int | None = None) -> Request:
        """A background reset of ``env_id`` (FoamBatchCore's request), in flight; ``context`` says what to
        do with its reply."""
        seed = self._episode_seed(env_id) if seed is None else seed
        self._in_flight[env_id] = ("reset", (context, seed))
        return self._reset_request(env_id, seed)

    def _absorb(self, replies: list[Reply]) -> None:
        """Turn replies into ready results, or into the resets they call for (submitted at once)."""
        follow_ups: list[Request] = []
        for reply in replies:
            what, context = self._in_flight.pop(reply.env_id)
            if what == "step":
                follow_ups += self._stepped(reply, context)
            else:
                follow_ups += self._was_reset(reply, *context)
        if follow_ups:
            self.backend.submit(follow_ups)

    def _stepped(self, reply: Reply, action: np.ndarray) -> list[Request]:
        obs, reward, terminated, truncated, info = self._step_result(reply, action)
        if not (terminated or truncated):
            self._ready[reply.env_id] = _Ready(obs, reward, terminated, truncated, [info])
            return []
        return [self._ended(reply.env_id, obs, reward, terminated, truncated, info)]

    def _ended(self, env_id: int, obs: np.ndarray, reward: float, terminated: bool, truncated: bool,
               info: dict[str, Any]) -> Request:
        """An episode ended: reset the env in the background; the step's result waits for the reset."""
        if isinstance(info.get("episode"), dict):  # the env's own record: say where it ran
            info["episode"].setdefault("node", self._tallies[env_id].node)
        ended = _Ready(obs, reward, terminated, truncated, [{"final_obs": obs, "final_info": info}, info])
        self._retried.discard(env_id)
        return self._sent_reset(env_id, ("ended", ended))

    def _was_reset(self, reply: Reply, context: tuple[str, Any], seed: int) -> list[Request]:
        env_id = reply.env_id
        if not reply.ok and reply.worker_died and env_id not in self._retried:  # one more try, same seed
            self._retried.add(env_id)
            return [self._sent_reset(env_id, context, seed)]
        self._retried.discard(env_id)
        kind, payload = context
        stale = self._tallies[env_id].obs
        if reply.ok:
            obs, info = self._start_tally(env_id, seed, *reply.value)
            if kind == "ended":  # the new episode's first observation, the ended one's final infos
                payload.obs, payload.infos[-1] = obs, info
                self._ready[env_id] = payload
            else:  # a retried reset: the action (chosen from ``stale``) is not applied
                self._ready[env_id] = _Ready(obs, 0.0, False, True, [info, {"final_obs": stale}])
            return []
        cause = _reset_cause(reply)
        if kind == "ended":  # the learner gets the ended step; the reset is retried when it is sent
            self._tallies[env_id].reset_failure = cause
            self._ready[env_id] = payload
            return []
        self._tallies[env_id] = _Tally(stale)  # no episode: a failed one of 0 iterations
        return [self._ended(env_id, *self._failed_step(self._tallies[env_id], payload, cause))]

    def _drain(self) -> None:
        """Wait for every request in flight and drop the results (before a new async_reset)."""
        while self._in_flight:
            for reply in self.backend.collect(POLL_S):
                self._in_flight.pop(reply.env_id, None)
        self._ready.clear()
        self._with_learner.clear()

    # ----- resuming ----------------------------------------------------------------------------
    def snapshot(self) -> dict[str, Any]:
        """Every env's state as JSON-ready data, enough for :meth:`replay` in another batch (another
        process; see the module docstring): ``envs`` (one entry per env), ``ready`` (the envs whose
        results wait, in order) and ``with_learner`` (the envs the last recv returned)."""
        envs = []
        for env_id in range(self.num_envs):
            entry = {**self._episode_entry(env_id), "reset_failure": self._tallies[env_id].reset_failure}
            what, context = self._in_flight.get(env_id, (None, None))
            if what == "step":
                entry["step"] = json_ready(context)
            elif what == "reset":
                (kind, payload), seed = context
                entry["running"] = False  # its tally is the ended episode's, or none: nothing to replay
                entry["reset"] = {"kind": kind, "seed": seed, "retried": env_id in self._retried,
                                  "payload": payload.to_json() if kind == "ended" else json_ready(payload)}
            if not entry["running"]:  # what replay restores of it: its last observation
                entry.update({"seed": None, "actions": [], "iterations": 0, "return": 0.0})
            if env_id in self._ready:
                entry["ready"] = self._ready[env_id].to_json()
            envs.append(entry)
        return {"envs": envs, "ready": list(self._ready), "with_learner": sorted(self._with_learner)}

    def replay(self, snapshot: dict[str, Any]) -> str:
        """Bring the batch to the state of ``snapshot``: replay the running episodes (as
        BatchedFoamEnv.replay), restore the envs without one, the seed streams, the waiting results and
        the learner's envs, and send the steps and resets that were in flight again. Returns "" when
        every env matches; otherwise why not, and the batch must be ``async_reset`` before it is used."""
        why = self._incomplete(snapshot)
        if why:
            return why
        if self._in_flight or self._ready or self._with_learner:
            self._drain()
        envs = snapshot["envs"]
        why = self._replay_episodes({i: entry for i, entry in enumerate(envs) if entry["running"]})
        if why:
            return why
        for env_id, entry in enumerate(envs):
            if not entry["running"]:  # an ended episode, or none since a reset failed
                self._tallies[env_id] = _Tally(np.asarray(entry["obs"], np.float32),
                                               reset_failure=entry["reset_failure"])
        self._restore_streams(envs)
        self._ready = OrderedDict((i, _Ready.from_json(envs[i]["ready"])) for i in snapshot["ready"])
        self._with_learner = set(snapshot["with_learner"])
        self._retried = {i for i, entry in enumerate(envs) if entry.get("reset", {}).get("retried")}
        self.backend.submit([self._resend(i, entry) for i, entry in enumerate(envs)
                             if "step" in entry or "reset" in entry])
        return ""

    def _incomplete(self, snapshot: Any) -> str:
        """Why ``snapshot`` cannot be this batch's state ("" if it can): each env must stand in exactly
        one place (with the learner, ready, or with a request in flight)."""
        envs = snapshot.get("envs") if isinstance(snapshot, dict) else None
        if not isinstance(envs, list) or len(envs) != self.num_envs:
            return f"the snapshot does not hold the {self.num_envs} envs of an asynchronous batch"
        places = [*snapshot.get("ready", []), *snapshot.get("with_learner", []),
                  *(i for i, entry in enumerate(envs) if "step" in entry or "reset" in entry)]
        if sorted(places) != list(range(self.num_envs)) \
                or any("ready" not in envs[i] for i in snapshot.get("ready", [])):
            return "the snapshot does not place each env once (with the learner, ready or in flight)"
        return ""

    def _resend(self, env_id: int, entry: dict[str, Any]) -> Request:
        """The request env ``env_id`` had in flight at the snapshot, in flight again."""
        if "step" in entry:
            return self._sent_step(env_id, np.asarray(entry["step"], np.float64))
        reset = entry["reset"]
        payload = (_Ready.from_json(reset["payload"]) if reset["kind"] == "ended"
                   else np.asarray(reset["payload"], np.float64))
        return self._sent_reset(env_id, (reset["kind"], payload), int(reset["seed"]))
