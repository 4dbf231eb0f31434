"""The old single home of the case code, kept so that ``from foam_bridge import case`` keeps working.

New code imports from the module that does the job:

- foam_bridge.template: the built-in case (mesh parameters, inlet turbulence) and the meshing steps
  every case shares (copy without results, blockMesh, patch names, cell count);
- foam_bridge.base_case: the base case built once per env (checks, inspection, the dry run of a
  user's case);
- foam_bridge.episode_case: the case of one episode (controlDict/fvSolution/relaxation text, the
  pause, restart and check copies);
- foam_bridge.user_case: what a user's case brings to its MDP (criterion, action box).
"""

from __future__ import annotations

from foam_bridge.base_case import (
    build_base_case,
    check_case,
    check_case_files,
    check_inlet_settable,
    dry_run,
    own_factors,
)
from foam_bridge.episode_case import (
    BRIDGE_DIR,
    CELLS_FUNCTION,
    CONTROL_INCLUDE,
    FIXED_RELAXATION,
    INLET_FUNCTION,
    PAUSE_FUNCTION,
    SIMPLE_INCLUDE,
    STATE_FIELD,
    CaseInfo,
    initial_state,
    make_uninterrupted,
    pause_boundaries,
    relaxation_fifo,
    relaxation_text,
    turbulence_fields,
    write_check_case,
    write_episode_case,
    write_restart,
)
from foam_bridge.template import (
    KINEMATIC_VISCOSITY,
    TEMPLATE_DIR,
    TURBULENCE_INTENSITY,
    TUTORIAL_CELLS,
    VISCOSITY_RATIO,
    cell_count,
    copy_case,
    inlet_turbulence,
    mesh_builtin,
    mesh_parameters,
    patch_names,
    run_application,
)

__all__ = ["BRIDGE_DIR", "CELLS_FUNCTION", "CONTROL_INCLUDE", "FIXED_RELAXATION", "INLET_FUNCTION",
           "KINEMATIC_VISCOSITY", "PAUSE_FUNCTION", "SIMPLE_INCLUDE", "STATE_FIELD", "TEMPLATE_DIR",
           "TURBULENCE_INTENSITY", "TUTORIAL_CELLS", "VISCOSITY_RATIO", "CaseInfo", "build_base_case",
           "cell_count", "check_case", "check_case_files", "check_inlet_settable",
           "copy_case", "dry_run", "initial_state", "inlet_turbulence", "make_uninterrupted",
           "mesh_builtin", "mesh_parameters", "own_factors", "patch_names", "pause_boundaries",
           "relaxation_fifo", "relaxation_text", "run_application", "turbulence_fields", "write_check_case",
           "write_episode_case", "write_restart"]
