#!/usr/bin/env bash
# The README's test command: set up (scripts/setup.sh), lint, then the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ruff check jaxsimrl foam_bridge tests benchmarks experiments docs
.venv/bin/python -m pytest -q "$@"
