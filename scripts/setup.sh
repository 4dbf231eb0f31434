#!/usr/bin/env bash
# Installs everything jaxsimrl needs on a fresh Debian/Ubuntu machine (idempotent):
# OpenFOAM (Debian's `openfoam` package, v1912) and its tutorials (`openfoam-examples`, which the tests
# run as users' cases), and a virtual environment in .venv with the pinned versions from constraints.txt.
set -euo pipefail
cd "$(dirname "$0")/.."

TUTORIALS=/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam
missing=()
command -v simpleFoam >/dev/null 2>&1 || missing+=(openfoam)
[ -d "$TUTORIALS" ] || missing+=(openfoam-examples)
if [ ${#missing[@]} -gt 0 ]; then
    SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -q
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q "${missing[@]}"
fi

PY=${PYTHON:-python3}
[ -x .venv/bin/python ] || "$PY" -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q -c constraints.txt -e ".[test]"
