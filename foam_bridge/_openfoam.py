"""Locating OpenFOAM (simpleFoam, blockMesh) and the clean environment the solver runs in.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

The solver never inherits the caller's shell: it gets ``PATH`` (the configured one), ``WM_PROJECT_DIR``
(Debian's v1912 needs it, or blockMesh fails with "Could not find mandatory etc entry 'controlDict'"),
``HOME`` (the case directory, so that no user ``~/.OpenFOAM`` setting leaks in), ``PWD`` and ``LANG``,
and the bridge's mark ``BRIDGE_MARK`` (the case directory): the reaper (foam_bridge._backends.reaper)
kills only processes that carry it, never a user's shell or paraFoam in a kept case.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from foam_bridge._errors import OpenFOAMNotFoundError

__all__ = ["BRIDGE_MARK", "INSTALL_HINT", "PROJECT_DIR_CANDIDATES", "OpenFOAM", "find_openfoam"]

INSTALL_HINT = (
    "install OpenFOAM v1912+ (Debian/Ubuntu: `sudo apt-get install -y openfoam`) or source your "
    "installation's etc/bashrc so that simpleFoam and blockMesh are on PATH"
)
#: Environment variable marking every process the bridge starts (its value: the case directory, resolved).
BRIDGE_MARK = "FOAM_BRIDGE_CASE"
#: Where WM_PROJECT_DIR may live when the caller's environment does not set it.
PROJECT_DIR_CANDIDATES = ("/usr/share/openfoam", "/usr/lib/openfoam/openfoam", "/opt/openfoam")


@dataclass(frozen=True)
class OpenFOAM:
    """An OpenFOAM installation: the binaries' PATH and the project directory (WM_PROJECT_DIR)."""

    path: str
    project_dir: str

    def executable(self, application: str) -> str:
        """Absolute path of an OpenFOAM application (``simpleFoam``, ``blockMesh``)."""
        found = shutil.which(application, path=self.path)
        if found is None:
            raise OpenFOAMNotFoundError(f"{application} not found on PATH={self.path!r}: {INSTALL_HINT}")
        return found

    def environment(self, case_dir: Path) -> dict[str, str]:
        """The clean environment an OpenFOAM application runs with in ``case_dir``."""
        return {
            "PATH": self.path,
            "WM_PROJECT_DIR": self.project_dir,
            "HOME": str(case_dir),
            "PWD": str(case_dir),
            "LANG": "C",
            "LC_ALL": "C",
            BRIDGE_MARK: os.path.realpath(case_dir),
        }


def find_openfoam(path: str | None = None) -> OpenFOAM:
    """Locate simpleFoam and blockMesh on ``path`` (None -> the caller's PATH).

    Raises OpenFOAMNotFoundError (one line, saying how to install OpenFOAM) when either is missing.
    """
    search_path = os.environ.get("PATH", "") if path is None else path
    for application in ("simpleFoam", "blockMesh", "foamDictionary"):
        if shutil.which(application, path=search_path) is None:
            raise OpenFOAMNotFoundError(
                f"OpenFOAM's {application} was not found on PATH={search_path!r}: {INSTALL_HINT}"
            )
    return OpenFOAM(path=search_path, project_dir=_project_dir(search_path))


def _project_dir(search_path: str) -> str:
    """WM_PROJECT_DIR: the caller's if valid, else a known location holding etc/controlDict."""
    simple_foam = Path(shutil.which("simpleFoam", path=search_path) or "").resolve()
    candidates = [os.environ.get("WM_PROJECT_DIR", ""), *PROJECT_DIR_CANDIDATES,
                  str(simple_foam.parent.parent / "share" / "openfoam")]
    for candidate in candidates:
        if candidate and (Path(candidate) / "etc" / "controlDict").is_file():
            return candidate
    raise OpenFOAMNotFoundError(
        f"found simpleFoam at {simple_foam} but no OpenFOAM project directory (etc/controlDict) in "
        f"{[c for c in candidates if c]}: set WM_PROJECT_DIR, or {INSTALL_HINT}"
    )
