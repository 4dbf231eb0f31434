"""How long a solver outlives a stop: Ctrl-C, SIGTERM and kill -9 of solve, train-foam and grid-foam.

    .venv/bin/python benchmarks/bench_stops.py --out /tmp/stops --repeats 3

Each command runs the built-in backward-facing step refined to ``--mesh-scale`` (2.5: 128k cells, about
0.3-0.5 s a SIMPLE iteration on 2 cores, so a step of 100 iterations lasts most of a minute), solve on it
as a user's case. Once every solver is ``--into`` iterations into a step, the signal goes to the command
(Ctrl-C to its whole process group, as a terminal sends it; SIGTERM and SIGKILL to the command alone) and
the time until no OpenFOAM process the bridge started is left is measured. Beside it, what a solver that
ran on to the end of its step would have cost: the iterations left in the step times the solver's own
seconds per iteration (its log). Prints a row per run and writes OUT/stops.jsonl and OUT/stops.md
(medians per command and signal, machine and date); run again, it adds what OUT/stops.jsonl lacks.
"""

from __future__ import annotations

import argparse
import collections
import datetime
import json
import os
import platform
import re
import shutil
import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path

from foamlib import FoamFile

from foam_bridge import _template as template
from foam_bridge._backends.reaper import processes_under

JAXSIMRL = str(Path(sys.executable).with_name("jaxsimrl"))
SIGNALS = {"Ctrl-C": signal.SIGINT, "SIGTERM": signal.SIGTERM, "kill -9": signal.SIGKILL}
INTERVAL = 100


def user_step(dest: Path, mesh_scale: float) -> Path:
    """The built-in step as a user's case (SIMPLEC, its own factors and residualControl), refined."""
    shutil.copytree(template.TEMPLATE_DIR, dest)
    with FoamFile(dest / "system" / "meshParameters") as params:
        params.update(template.mesh_parameters(mesh_scale, 0.0127))
    solution = dest / "system" / "fvSolution"
    solution.write_text(solution.read_text()
                        + '\nrelaxationFactors { fields { p 0.8; } equations { U 0.9; ".*" 0.8; } }\n')
    return dest


def commands(root: Path, mesh_scale: float) -> dict[str, list[str]]:
    """Each command's argv, writing under ``root``."""
    return {
        "solve": [JAXSIMRL, "solve", str(user_step(root / "case", mesh_scale)), "--out", str(root / "out"),
                  "--controller", "learned"],
        "train-foam": [JAXSIMRL, "train-foam", "--mesh-scale", str(mesh_scale), "--pool", "2",
                       "--steps-per-update", "8", "--episodes", "50", "--out", str(root / "run")],
        "grid-foam": [JAXSIMRL, "grid-foam", "--mesh-scale", str(mesh_scale), "--alpha-u", "0.95",
                      "--alpha-p", "0.9", "0.95", "--pool", "2", "--out", str(root / "grid")],
    }


def _logs(root: Path) -> list[Path]:
    """The episodes' solver logs (not those of the case checks' one-iteration dry runs); none while a
    scratch directory vanishes under the walk."""
    try:
        return [log for log in root.rglob("log.simpleFoam") if "episode" in log.parts]
    except FileNotFoundError:
        return []


def _progress(log: Path) -> tuple[int, float]:
    """(iterations started, the solver's seconds per iteration so far) from a running solver's log."""
    text = log.read_text(errors="replace")
    times = [float(t) for t in re.findall(r"ExecutionTime = ([0-9.eE+-]+) s", text)]
    rate = (times[-1] - times[0]) / (len(times) - 1) if len(times) > 1 else float("nan")
    return text.count("\nTime = "), rate


def one_stop(name: str, argv: list[str], sig: signal.Signals, root: Path, into: int, solvers: int) -> dict:
    """Run ``argv`` until every solver is ``into`` iterations into a step, send ``sig``, time the stop."""
    # Ctrl-C's default handler back: a benchmark started in the background (nohup ... &) hands its
    # children SIGINT ignored, and Python then installs no KeyboardInterrupt
    process = subprocess.Popen(argv, env={**os.environ, "TMPDIR": str(root)}, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL, start_new_session=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # noqa: PLW1509
    try:
        deadline = time.monotonic() + 900
        while True:
            seen = [_progress(log) for log in _logs(root)]
            if len(seen) >= solvers and min(it % INTERVAL for it, _ in seen) >= into:
                break
            if process.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"{name}: no solver {into} iterations into a step ({seen})")
            time.sleep(0.1)
        sent = time.monotonic()
        if sig == signal.SIGINT:
            os.killpg(process.pid, sig)
        else:
            process.send_signal(sig)
        while processes_under(root) and time.monotonic() - sent < 300:
            time.sleep(0.05)
        took = time.monotonic() - sent
        process.wait(timeout=60)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    run_on = max((INTERVAL - it % INTERVAL) * rate for it, rate in seen)
    return {"command": name, "signal": sig.name, "solvers": len(seen), "iterations": [it for it, _ in seen],
            "s_per_iteration": round(max(rate for _, rate in seen), 3), "stop_s": round(took, 2),
            "to_end_of_step_s": round(run_on, 1), "exit_code": process.returncode}


def report(rows: list[dict], out: Path, mesh_scale: float) -> str:
    """The markdown table of medians per command and signal."""
    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), platform.processor())
    lines = [f"{datetime.date.today()}, {cpu}, {os.cpu_count()} cores; built-in step at mesh scale "
             f"{mesh_scale:g}; median over {len(rows) // 9 or 1} run(s) each (benchmarks/bench_stops.py)", "",
             "| command | signal | no solver left after (s) | running on to the end of the step (s) |",
             "|---|---|---|---|"]
    for name in ("solve", "train-foam", "grid-foam"):
        for sig in SIGNALS.values():
            mine = [row for row in rows if row["command"] == name and row["signal"] == sig.name]
            if mine:
                lines.append(f"| {name} | {sig.name} | {statistics.median(r['stop_s'] for r in mine):.2f} | "
                             f"{statistics.median(r['to_end_of_step_s'] for r in mine):.0f} |")
    (out / "stops.md").write_text("\n".join(lines) + "\n")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--mesh-scale", type=float, default=2.5)
    parser.add_argument("--into", type=int, default=5, help="iterations into a step before the signal")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    log = args.out / "stops.jsonl"
    rows = [json.loads(line) for line in log.read_text().splitlines()] if log.is_file() else []
    done = collections.Counter((row["command"], row["signal"]) for row in rows)  # resumes a stopped run
    for repeat in range(args.repeats):
        for name in ("solve", "train-foam", "grid-foam"):
            for sig in SIGNALS.values():
                if done[(name, sig.name)] > repeat:
                    continue
                root = args.out / f"{name}-{sig.name}-{repeat}"
                shutil.rmtree(root, ignore_errors=True)
                root.mkdir()
                argv = commands(root, args.mesh_scale)[name]
                row = one_stop(name, argv, sig, root, args.into, 1 if name == "solve" else 2)
                rows.append(row)
                print(json.dumps(row), flush=True)
                with open(log, "a") as handle:
                    handle.write(json.dumps(row) + "\n")
                shutil.rmtree(root, ignore_errors=True)
    print(report(rows, args.out, args.mesh_scale))


if __name__ == "__main__":
    main()
