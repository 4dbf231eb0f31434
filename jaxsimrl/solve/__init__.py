"""``jaxsimrl solve``: converge a user's OpenFOAM case with a trained controller, never worse than its own
settings. One public call, :func:`solve_case` (jaxsimrl.solve.runner); the command is jaxsimrl/cli/solve.py.
"""

from jaxsimrl.solve.controller import DEFAULT_CONTROLLER, Controller, load_controller
from jaxsimrl.solve.report import SolveReport
from jaxsimrl.solve.runner import solve_case
from jaxsimrl.solve.watchdog import WatchdogSettings

__all__ = ["DEFAULT_CONTROLLER", "Controller", "SolveReport", "WatchdogSettings", "load_controller",
           "solve_case"]
