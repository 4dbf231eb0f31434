"""Environments: the shared protocol, the pure-JAX Lorenz env and its gymnasium wrapper.

Names load lazily so that ``jaxsimrl.envs.protocol`` (used by JAX-free host envs) does not pull in JAX.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "Environment": "jaxsimrl.envs.protocol",
    "Step": "jaxsimrl.envs.protocol",
    "BoxSpec": "jaxsimrl.envs.protocol",
    "Lorenz": "jaxsimrl.envs.lorenz",
    "LorenzParams": "jaxsimrl.envs.lorenz",
    "LorenzState": "jaxsimrl.envs.lorenz",
    "LorenzGymEnv": "jaxsimrl.envs.gym_lorenz",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'jaxsimrl.envs' has no attribute {name!r}")
    return getattr(importlib.import_module(_EXPORTS[name]), name)


def __dir__() -> list[str]:
    return __all__
