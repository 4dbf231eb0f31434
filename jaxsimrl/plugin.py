"""The plugin contract: how an application (a simulation to control) plugs into the core.

The core (every module of jaxsimrl outside ``jaxsimrl.apps``) names no application. An application is a
package that defines ``APP``, an :class:`App`, and is found either as a subpackage of ``jaxsimrl.apps``
or in any installed distribution through the entry point group ``jaxsimrl.apps``
(``name = "package.module"``).
What an App gives, as "module:name" strings so that finding it imports nothing heavy (``jaxsimrl --help``
stays instant):

- ``env``: the name its runs record as config.json's ``"env"``;
- ``commands``: modules that each add CLI subcommands (``register(subparsers)``, as the core's own);
- ``env_spec``: builds a run's :class:`jaxsimrl.policy.spec.EnvSpec` from its config.json record;
- ``rollout``: ``LoadedPolicy.rollout`` for its runs, when the env is not a pure-JAX one;
- ``failed_outcomes``: the episode outcomes (episodes.csv's ``outcome``) that count as failures.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from importlib.metadata import entry_points
from typing import Any

__all__ = ["App", "application", "applications", "load"]

#: Where the project's own applications live, and the entry point group of other distributions'.
APPS_PACKAGE = ENTRY_POINT_GROUP = "jaxsimrl.apps"


@dataclass(frozen=True)
class App:
    """What an application plugs into the core (see the module docstring)."""

    env: str
    commands: tuple[str, ...] = ()
    env_spec: str | None = None
    rollout: str | None = None
    failed_outcomes: frozenset[str] = frozenset()


def load(target: str) -> Callable[..., Any]:
    """The object a "module:name" string names."""
    module, _, name = target.partition(":")
    return getattr(importlib.import_module(module), name)


@cache
def applications() -> tuple[App, ...]:
    """Every application: this package's subpackages, then the entry points' (by env name, first wins)."""
    found: dict[str, App] = {}
    apps = importlib.import_module(APPS_PACKAGE)
    modules = [f"{APPS_PACKAGE}.{info.name}" for info in pkgutil.iter_modules(apps.__path__) if info.ispkg]
    modules += [point.value for point in entry_points(group=ENTRY_POINT_GROUP)]
    for module in modules:
        app = getattr(importlib.import_module(module), "APP", None)
        if isinstance(app, App):
            found.setdefault(app.env, app)
    return tuple(found.values())


def application(env: str | None) -> App | None:
    """The application whose runs record ``env`` (None if none does)."""
    return next((app for app in applications() if app.env == env), None)
