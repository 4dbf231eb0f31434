#!/usr/bin/env bash
# The README's test command: set up (scripts/setup.sh), lint, then the whole test suite.
# The suite runs on 2 pytest-xdist workers, a test file per worker at a time (--dist loadfile): a file's
# module-scoped fixtures (real training runs) are built once, and the Ray cluster tests (one file) never
# run beside each other. `pytest tests/x.py` alone still runs in one process.
# `--quick` (anywhere among the arguments) runs the quick tier instead: the same, with `-m "not slow"`
# (no long fault, long-step, Ray cluster or real-training test; docs/development.md). Every other
# argument goes to pytest as it is. CI (.ci/run) runs it without --quick: the whole suite.
set -euo pipefail
cd "$(dirname "$0")/.."
args=()
for arg in "$@"; do
    if [[ "$arg" == "--quick" ]]; then
        args+=(-m "not slow")
    else
        args+=("$arg")
    fi
done
bash scripts/setup.sh
.venv/bin/ruff check jaxsimrl foam_bridge atomicfile tests benchmarks experiments docs
.venv/bin/python -m pytest -q -n 2 --dist loadfile ${args[@]+"${args[@]}"}
