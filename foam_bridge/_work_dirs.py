"""Where an env's case directories live: the work directory (a given one, or a fresh temporary one),
checked for what OpenFOAM cannot run in, and paths made absolute for workers and the solver.

Internal to foam_bridge; names here may change.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from foam_bridge._config import FoamEnvConfig, absolute_path


def work_root(cfg: FoamEnvConfig, work_dir: Path | str | None = None,
              prefix: str = "foam_bridge_") -> tuple[Path, bool]:
    """The parent of the case directories and whether it is a fresh temporary directory.

    ``work_dir``, else ``cfg.work_dir`` (created if missing), else a new temporary directory named
    ``prefix...``, which the caller removes when it closes (unless ``cfg.keep_cases``). A path with
    whitespace is a one-line ValueError: OpenFOAM (v1912) cannot run a case there (its foamDictionary and
    solvers fail with "Could not find mandatory etc entry 'controlDict'"). A user's ``case_dir`` may have
    whitespace: it is only copied.
    """
    chosen = work_dir if work_dir is not None else cfg.work_dir
    if chosen is None:
        _check_no_whitespace(Path(tempfile.gettempdir()), "the temporary directory (TMPDIR)")
        return Path(tempfile.mkdtemp(prefix=prefix)).resolve(), True
    root = absolute_path(chosen)
    _check_no_whitespace(root, "work_dir")
    root.mkdir(parents=True, exist_ok=True)
    return root, False


def _check_no_whitespace(path: Path, what: str) -> None:
    if any(char.isspace() for char in str(path)):
        raise ValueError(f"{what} {str(path)!r} contains whitespace, where OpenFOAM cannot run a case; "
                         f"choose a directory without spaces")

