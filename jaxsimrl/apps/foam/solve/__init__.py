"""``jaxsimrl solve``: converge a user's OpenFOAM case with a trained controller, never worse than its own
settings. One public call, :func:`solve_case` (jaxsimrl.apps.foam.solve.runner); the command is
jaxsimrl/apps/foam/cli/solve.py.
"""

from jaxsimrl.apps.foam.solve.controller import DEFAULT_CONTROLLER, Controller, load_controller
from jaxsimrl.apps.foam.solve.report import SolveReport
from jaxsimrl.apps.foam.solve.runner import solve_case
from jaxsimrl.apps.foam.solve.watchdog import WatchdogSettings

__all__ = ["DEFAULT_CONTROLLER", "Controller", "SolveReport", "WatchdogSettings", "load_controller",
           "solve_case"]
