"""Reading a user's OpenFOAM dictionaries the way OpenFOAM itself reads them (``foamDictionary -expand``).

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

A user's case may use anything OpenFOAM's parser understands: ``#include``/``#includeFunc``/
``#includeEtc``, ``$var`` substitutions, regular-expression keys, ``#codeStream``. The bridge never
re-serialises those files (that loses or breaks what it does not understand). To *read* a value it asks
OpenFOAM's own ``foamDictionary -expand``, which prints the file as the solver will see it (directives
executed, variables substituted), and parses that plain text with foamlib. To *change* something, the
bridge appends an ``#include`` of a file it writes itself (see foam_bridge._episode_case).

A file OpenFOAM cannot read is a one-line :class:`foam_bridge._errors.CaseError` naming the file and,
where the message allows, the entry.
"""

from __future__ import annotations

import gzip
import re
import subprocess
from pathlib import Path
from typing import Any

from foamlib import FoamFile

from foam_bridge._errors import CaseError
from foam_bridge._openfoam import OpenFOAM

__all__ = ["TIMEOUT_S", "expand", "expanded_text", "fatal_message", "lookup"]

#: What OpenFOAM v1912 says when asked to compile a #codeStream/#calc as root.
_ROOT_REFUSAL = "administrator rights"
_CODE_DIRECTIVE = re.compile(r"#(codeStream|calc)\b")
_KEYWORD = re.compile(r"^\s*([A-Za-z_\"][^\s{;]*)\s*(?:$|[{(\[]|\S)")
#: foamDictionary needs more than a dictionary read; a few seconds is already generous.
TIMEOUT_S = 60.0


def expand(openfoam: OpenFOAM, case: Path, relative: str, parse: bool = True) -> dict[str, Any]:
    """The dictionary ``case/relative`` as OpenFOAM reads it (directives executed), as plain Python.

    One-line CaseError if OpenFOAM cannot read it (missing, a syntax error, a #codeStream refused as
    root, ...). ``parse=False`` only checks that OpenFOAM can read it (returns {}): foamlib takes
    seconds over a blockMeshDict's nested lists.
    """
    text = expanded_text(openfoam, case, relative)
    if not parse:
        return {}
    path = case / relative
    try:
        return _plain(FoamFile.loads(text)) if text.strip() else {}
    except Exception as err:  # noqa: BLE001 - foamlib's own errors carry the position
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise CaseError(f"{path}: cannot parse OpenFOAM's expansion of it ({first})") from None


def expanded_text(openfoam: OpenFOAM, case: Path, relative: str) -> str:
    """The text of ``case/relative`` as ``foamDictionary -expand`` prints it (from its FoamFile header
    on): every top-level entry on one line, directives executed, variables substituted. Same one-line
    CaseErrors as :func:`expand`."""
    path = case / relative
    if not path.is_file() and not Path(f"{path}.gz").is_file():
        raise CaseError(f"case {case}: missing {relative}")
    try:
        result = subprocess.run(
            [openfoam.executable("foamDictionary"), "-case", str(case), "-precision", "17", "-expand",
             str(path)], cwd=case,
            env=openfoam.environment(case), stdin=subprocess.DEVNULL, capture_output=True, text=True,
            errors="replace", timeout=TIMEOUT_S, check=False,
        )
    except subprocess.TimeoutExpired:
        raise CaseError(f"{path}: foamDictionary did not read it within {TIMEOUT_S:g} s") from None
    if result.returncode != 0:
        raise CaseError(_read_error(path, relative, result.stdout + result.stderr))
    return _strip_banner(result.stdout)


def _strip_banner(output: str) -> str:
    """foamDictionary's output from its ``FoamFile`` header on (warnings and the banner dropped)."""
    match = re.search(r"^FoamFile\b", output, re.MULTILINE)
    return output[match.start():] if match else ""


def _read_error(path: Path, relative: str, output: str) -> str:
    """One line out of a FOAM FATAL message: what went wrong, in which file and entry."""
    if _ROOT_REFUSAL in output:
        entry = _code_entry(path)
        where = f"entry {entry!r} uses #codeStream/#calc, which" if entry else "a #codeStream/#calc"
        return (f"{path}: {where} OpenFOAM v1912 refuses to compile when run as root; run as a normal "
                f"user or replace it with plain values")
    return f"{path}: OpenFOAM cannot read {relative}: {fatal_message(output) or 'foamDictionary failed'}"


def fatal_message(output: str) -> str:
    """One line out of an application's FOAM FATAL (IO) ERROR: its message line and, where OpenFOAM
    names one, the ``file: ...`` position; "" if the output holds no FOAM FATAL message."""
    lines = [line.strip() for line in output.splitlines() if line.strip()]
    message = next((lines[i + 1] for i, line in enumerate(lines[:-1]) if "FOAM FATAL" in line), "")
    position = next((line for line in lines if line.startswith("file:")), "")
    return "; ".join(part for part in (message, position) if part)


def _code_entry(path: Path) -> str | None:
    """The top-level keyword whose value holds the first #codeStream/#calc of the file, if any."""
    raw = _read_text(path)
    keyword = None
    depth = 0
    for line in raw.splitlines():
        if depth == 0 and (match := _KEYWORD.match(line)) and not line.lstrip().startswith(("#", "//")):
            keyword = match.group(1)
        if _CODE_DIRECTIVE.search(line):
            return keyword
        depth += line.count("{") + line.count("(") - line.count("}") - line.count(")")
    return None


def _read_text(path: Path) -> str:
    if path.is_file():
        return path.read_text(errors="replace")
    return gzip.decompress(Path(f"{path}.gz").read_bytes()).decode(errors="replace")


def lookup(tree: dict[str, Any], scoped: str) -> Any:
    """``tree["a"]["b"]`` for ``"a/b"``, with OpenFOAM's rules: an exact key first, else the last
    regular-expression key (``"(a|b)"``) that matches. KeyError if nothing matches."""
    node: Any = tree
    for part in scoped.split("/"):
        if not isinstance(node, dict):
            raise KeyError(scoped)
        node = node[_match_key(node, part, scoped)]
    return node


def _match_key(node: dict[str, Any], part: str, scoped: str) -> str:
    if part in node:
        return part
    for key in reversed(list(node)):
        if key.startswith('"') and key.endswith('"') and re.fullmatch(key[1:-1], part):
            return key
    raise KeyError(scoped)


def _plain(node: Any) -> Any:
    """foamlib's parsed mapping as nested plain dicts (its sub-dictionaries may be proxy objects)."""
    if hasattr(node, "as_dict"):
        node = node.as_dict()
    if isinstance(node, dict):
        return {key: _plain(value) for key, value in node.items()}
    return node
