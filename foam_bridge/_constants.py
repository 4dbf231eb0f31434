"""The numbers of the simpleFoam solver-control environment: the paper's reference values and
convergence criteria, the built-in case's defaults, the usable mesh floor and the observation's bound.

Internal to foam_bridge (its users import these names from ``foam_bridge``, or from
foam_bridge._config, which re-exports them beside the config they describe); names here may change.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

#: The paper's reference velocity (m/s); the observation divides |U|^2 by U_REF**2.
U_REF = 44.2
#: The tutorial's (and the paper's) step height h in metres.
STEP_HEIGHT_H = 0.0127
#: The paper's training criterion: initial residuals of U, k, omega < 1e-3 and p < 5e-2.
TRAIN_CONVERGENCE: Mapping[str, float] = MappingProxyType({"U": 1e-3, "k": 1e-3, "omega": 1e-3, "p": 5e-2})
#: The paper's test criterion: U, k, omega < 5e-4 (p < 5e-2).
TEST_CONVERGENCE: Mapping[str, float] = MappingProxyType({"U": 5e-4, "k": 5e-4, "omega": 5e-4, "p": 5e-2})

#: A convergence threshold no residual meets: a run with it goes on to its iteration count.
NEVER_CONVERGED = 1e-30

#: The built-in action box per factor (the paper's): [0.2, 0.95] for alpha_u, alpha_p (and alpha_t).
BUILTIN_ACTION_BOUNDS = (0.2, 0.95)
#: The built-in case's defaults, the paper's code's (and the tutorial's): SIMPLEC, k/omega relaxed at
#: 0.8, inlet speed uniform in [35, 65] m/s, inlet turbulence from intensity 6.1e-4 and nu_t/nu 0.009.
BUILTIN_SIMPLE_VARIANT = "SIMPLEC"
BUILTIN_RELAX_K_OMEGA = 0.8
BUILTIN_INLET_VELOCITY = (35.0, 65.0)
PAPER_INLET_TURBULENCE = (6.1e-4, 0.009)
#: Smallest mesh_scale of the built-in case measured usable (see FoamEnvConfig.mesh_scale).
MESH_SCALE_USABLE_MIN = 0.4
#: Every observation entry is clipped into [-OBSERVATION_BOUND, OBSERVATION_BOUND] (NaN -> the bound):
#: the last line of defence for a learner's normaliser; divergence detection ends episodes long before.
OBSERVATION_BOUND = 1e6
