"""Post-processing for the CFD model validation of the backward-facing step (paper, "CFD model").

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

Pure helpers, no solver: the sampling dictionary handed to ``simpleFoam -postProcess -dict``, parsers of
what OpenFOAM's ``sets`` and ``surfaces`` function objects write in ``setFormat raw`` /
``surfaceFormat raw``, and the wall quantities compared with Driver & Seegmiller (1985):

- pressure coefficient ``Cp = (p - p_ref) / (U_ref^2 / 2)`` (simpleFoam's p is kinematic, p/rho), with
  p_ref the lower-wall pressure at x/h = 40, as the NASA Turbulence Modeling Resource (TMR) shifts both
  the experiment's and its CFD's Cp to about 0 there;
- skin-friction coefficient ``Cf = -tau_x / (U_ref^2 / 2)`` on the lower wall, from OpenFOAM's
  ``wallShearStress`` (see :func:`skin_friction_coefficient` for the sign);
- the reattachment length: where Cf last changes sign from negative to positive behind the step,
  interpolated linearly between the two faces around the sign change.

Lengths are in metres on input and in step heights h on output (x/h = 0 at the step, y/h = 0 on the
floor behind it).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from foam_bridge._config import STEP_HEIGHT_H, U_REF

__all__ = ["CP_REFERENCE_XH", "EXPERIMENT_REATTACHMENT_ERROR_XH", "EXPERIMENT_REATTACHMENT_XH",
           "PLANE_FUNCTION", "PLANE_SURFACE", "PROFILES_FUNCTION", "TMR_SST_REATTACHMENT_XH", "WALL_FUNCTION",
           "WALL_PATCH", "WallCoefficients", "plane_velocity", "pressure_coefficient", "read_raw",
           "reattachment_length", "rising_zero_crossings", "sampling_dict", "skin_friction_coefficient",
           "station_name", "velocity_profile", "wall_coefficients"]

#: Driver & Seegmiller's measured reattachment length (x/h) and its uncertainty.
EXPERIMENT_REATTACHMENT_XH = 6.26
EXPERIMENT_REATTACHMENT_ERROR_XH = 0.10
#: NASA TMR's k-omega SST (SSTm, CFL3D and FUN3D, second-finest grid): "Reattachment is predicted by
#: the SSTm model near x/H = 6.50" (turbmodels backstep_val_sst page).
TMR_SST_REATTACHMENT_XH = 6.50
#: The x/h at which Cp is zeroed (TMR: "Cp values have been shifted so that Cp is close to zero near
#: x/H=40").
CP_REFERENCE_XH = 40.0
#: Names of the function objects in :func:`sampling_dict` (also the postProcessing/ subdirectories).
PROFILES_FUNCTION = "validationProfiles"
WALL_FUNCTION = "validationWall"
PLANE_FUNCTION = "validationPlane"
WALL_PATCH = "lowerWall"
PLANE_SURFACE = "midPlane"


@dataclass(frozen=True)
class WallCoefficients:
    """Cp and Cf along the lower wall's horizontal faces, sorted by x/h (the step face left out)."""

    x_h: np.ndarray
    cp: np.ndarray
    cf: np.ndarray


def station_name(x_h: float) -> str:
    """Set name of the profile at x/h (OpenFOAM names the file ``<name>_U.xy``): 4 -> ``xh4``."""
    return "xh" + f"{x_h:g}".replace(".", "p").replace("-", "m")


def sampling_dict(stations_xh: Sequence[float], y_range_h: tuple[float, float], z_mid: float,
                  step_height: float = STEP_HEIGHT_H, points: int = 200) -> str:
    """The functions dictionary for ``simpleFoam -postProcess -dict``: one call writes everything.

    - ``wallShearStress`` on the lower wall (needs the turbulence model, hence simpleFoam's
      ``-postProcess`` rather than the bare ``postProcess`` utility);
    - ``sets``: U along vertical lines at the stations, from y_range_h[0] to y_range_h[1] (in h), in
      the plane z = z_mid (m), ``points`` uniform points each, cellPoint interpolation;
    - ``surfaces``: p and wallShearStress on the lower-wall faces, and U on the cutting plane z = z_mid
      (one value per cell, at the cut face's centre), all raw.
    Function objects run in order, so the sampled wallShearStress is the one just computed.
    """
    if not stations_xh:
        raise ValueError("sampling_dict: give at least one x/h station")
    if points < 2:
        raise ValueError(f"sampling_dict: points must be >= 2, got {points}")
    y0, y1 = (value * step_height for value in y_range_h)
    lines = []
    for x_h in stations_xh:
        x = x_h * step_height
        lines.append(f"            {station_name(x_h)} {{ type uniform; axis y; "
                     f"start ({x!r} {y0!r} {z_mid!r}); end ({x!r} {y1!r} {z_mid!r}); nPoints {points}; }}")
    set_lines = "\n".join(lines)
    return f"""FoamFile {{ version 2.0; format ascii; class dictionary; object validationDict; }}
functions
{{
    wallShearStress
    {{
        type wallShearStress; libs ("libfieldFunctionObjects.so"); patches ({WALL_PATCH});
        writeControl writeTime;
    }}
    {PROFILES_FUNCTION}
    {{
        type sets; libs ("libsampling.so"); interpolationScheme cellPoint; setFormat raw; fields (U);
        sets
        (
{set_lines}
        );
    }}
    {WALL_FUNCTION}
    {{
        type surfaces; libs ("libsampling.so"); interpolationScheme cell; surfaceFormat raw;
        fields (p wallShearStress);
        surfaces ( {WALL_PATCH} {{ type patch; patches ({WALL_PATCH}); interpolate false; }} );
    }}
    {PLANE_FUNCTION}
    {{
        type surfaces; libs ("libsampling.so"); interpolationScheme cell; surfaceFormat raw; fields (U);
        surfaces ( {PLANE_SURFACE} {{ type cuttingPlane; planeType pointAndNormal;
            pointAndNormalDict {{ point (0 0 {z_mid!r}); normal (0 0 1); }}
            interpolate true; }} );
    }}
}}
"""


def read_raw(path: str | os.PathLike[str]) -> np.ndarray:
    """The numbers of an OpenFOAM raw set/surface file as a 2-D array (``#`` header lines skipped).

    One-line ValueError if the file holds no data row or rows of different lengths.
    """
    rows = []
    with open(path) as handle:
        for line in handle:
            text = line.strip()
            if text and not text.startswith("#"):
                rows.append([float(value) for value in text.split()])
    if not rows:
        raise ValueError(f"{path}: no data rows")
    if len({len(row) for row in rows}) != 1:
        raise ValueError(f"{path}: rows of different lengths")
    return np.asarray(rows)


def velocity_profile(raw_set: np.ndarray, step_height: float = STEP_HEIGHT_H,
                     u_ref: float = U_REF) -> tuple[np.ndarray, np.ndarray]:
    """(y/h, Ux/U_ref) from a raw ``axis y`` set of U (columns y, Ux, Uy, Uz)."""
    if raw_set.ndim != 2 or raw_set.shape[1] != 4:
        raise ValueError(f"velocity_profile: expected columns (y, Ux, Uy, Uz), got shape {raw_set.shape}")
    return raw_set[:, 0] / step_height, raw_set[:, 1] / u_ref


def pressure_coefficient(p: np.ndarray, p_ref: float, u_ref: float = U_REF) -> np.ndarray:
    """Cp = (p - p_ref) / (U_ref^2 / 2), with simpleFoam's kinematic pressure (p / rho)."""
    return (np.asarray(p, float) - p_ref) / (0.5 * u_ref**2)


def skin_friction_coefficient(wall_shear_x: np.ndarray, u_ref: float = U_REF) -> np.ndarray:
    """Cf of the lower wall from the x component of OpenFOAM's (kinematic) ``wallShearStress``.

    OpenFOAM writes ``-n . R_eff`` with n the wall's outward normal and R_eff = -nu_eff (grad U + ...),
    i.e. the stress the wall exerts on the fluid. On the lower wall (n = -y) that is -nu_eff dUx/dy:
    negative where the near-wall flow goes downstream. Cf takes the usual sign, positive for attached
    flow and negative in the recirculation bubble, so it is minus that over U_ref^2 / 2.
    """
    return -np.asarray(wall_shear_x, float) / (0.5 * u_ref**2)


def wall_coefficients(p_raw: np.ndarray, shear_raw: np.ndarray, step_height: float = STEP_HEIGHT_H,
                      u_ref: float = U_REF, p_ref_xh: float = CP_REFERENCE_XH) -> WallCoefficients:
    """Cp and Cf on the lower wall from the raw surface files of p (x y z p) and wallShearStress.

    The vertical step face (x = 0) is left out; the others are sorted by x. Cp is zeroed at
    ``p_ref_xh`` (linear interpolation along the wall).
    """
    if p_raw.shape[0] != shear_raw.shape[0] or not np.allclose(p_raw[:, :3], shear_raw[:, :3]):
        raise ValueError("wall_coefficients: the p and wallShearStress files hold different faces")
    x_h = p_raw[:, 0] / step_height
    keep = np.abs(x_h) > 1e-6
    order = np.argsort(x_h[keep])
    x_h, p, tau_x = x_h[keep][order], p_raw[keep, 3][order], shear_raw[keep, 3][order]
    if not x_h[0] <= p_ref_xh <= x_h[-1]:
        raise ValueError(f"wall_coefficients: the Cp reference x/h = {p_ref_xh:g} lies outside the wall "
                         f"({x_h[0]:.3g} to {x_h[-1]:.3g})")
    p_ref = float(np.interp(p_ref_xh, x_h, p))
    cp = pressure_coefficient(p, p_ref, u_ref)
    return WallCoefficients(x_h, cp, skin_friction_coefficient(tau_x, u_ref))


def rising_zero_crossings(x: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Every x where ``values`` goes from < 0 to >= 0, by linear interpolation (x ascending)."""
    x, values = np.asarray(x, float), np.asarray(values, float)
    index = np.flatnonzero((values[:-1] < 0) & (values[1:] >= 0))
    x0, x1, v0, v1 = x[index], x[index + 1], values[index], values[index + 1]
    return x0 - v0 * (x1 - x0) / (v1 - v0)


def reattachment_length(x_h: np.ndarray, cf: np.ndarray) -> float:
    """x/h of reattachment: the last rising zero crossing of Cf behind the step (x/h > 0).

    The last, because a corner vortex can make Cf positive right behind the step and change sign
    once more before the main bubble. One-line ValueError if Cf never turns positive behind the step.
    """
    x_h, cf = np.asarray(x_h, float), np.asarray(cf, float)
    behind = x_h > 0
    crossings = rising_zero_crossings(x_h[behind], cf[behind])
    if crossings.size == 0:
        raise ValueError("reattachment_length: Cf never changes from negative to positive behind the step")
    return float(crossings[-1])


def plane_velocity(raw_plane: np.ndarray, step_height: float = STEP_HEIGHT_H,
                   u_ref: float = U_REF) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x/h, y/h, |U|/U_ref) per cell from the raw cutting-plane file of U (x y z Ux Uy Uz)."""
    if raw_plane.ndim != 2 or raw_plane.shape[1] != 6:
        raise ValueError(f"plane_velocity: expected columns (x, y, z, Ux, Uy, Uz), got {raw_plane.shape}")
    speed = np.linalg.norm(raw_plane[:, 3:6], axis=1) / u_ref
    return raw_plane[:, 0] / step_height, raw_plane[:, 1] / step_height, speed
