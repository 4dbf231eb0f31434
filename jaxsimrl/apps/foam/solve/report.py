"""``solve``'s report: ``OUT/solve.json`` (atomic), ``OUT/solve.png`` and the printed summary.

solve.json holds: status ("incomplete" while running, "interrupted", "failed", "complete"), the case and
output, the controller's provenance, the settings (criterion, box, confirmation factor, budget, the case
field observed for each field the controller observes), the result (outcome, converged per the
confirmation check, iterations, wall time, the solver's CPU time, where the fields come from, solve's
overhead beyond the solver's own work), every step's factors and residuals, the fallback events, the
convergence checks, the per-iteration residual histories and, with --compare, the comparison runs side
by side with the ratios controller / own and whether their converged results agree with the
controller's (``agreement``, jaxsimrl.apps.foam.solve.agreement).
"""

from __future__ import annotations

import datetime
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from foam_bridge import K_OMEGA_ACTION, LogParser, field_residual
from jaxsimrl.apps.foam.solve.agreement import spread_line, summary_line
from jaxsimrl.apps.foam.solve.answer import SETTLED, answer_lines, answer_result, succeeded
from jaxsimrl.apps.foam.solve.criterion import describe
from jaxsimrl.runs.atomic import atomic_write_bytes, atomic_write_json

SOLVE_JSON = "solve.json"
SOLVE_PNG = "solve.png"


@dataclass(frozen=True)
class SolveReport:
    """The report of one solve (``data`` is solve.json's content)."""

    data: dict[str, Any]

    @property
    def converged(self) -> bool:
        return bool(self.data["result"]["converged"])

    @property
    def succeeded(self) -> bool:
        """Converged or settled: an answer to take (exit code 0)."""
        return succeeded(self.data["result"])

    @property
    def iterations(self) -> int:
        return int(self.data["result"]["iterations"])

    @property
    def fallback(self) -> list[dict[str, Any]]:
        return list(self.data["fallback"])

    def summary(self) -> str:
        """The printed summary: a few lines."""
        result = self.data["result"]
        lines = [f"{self.data['case']} -> {self.data['out']}",
                 f"  {result['outcome']} "
                 f"({_verdict(result)}) "
                 f"after {result['iterations']} iterations, {result['wall_time_s']:.1f} s wall, solver CPU "
                 f"{result['solver_cpu_time_s']:.1f} s; fields from {result['fields_from']}",
                 *_criterion_line(self.data), *answer_lines(self.data),
                 f"  overhead beyond the solver's own work: {_percent(result['overhead_fraction'])} of wall "
                 f"time"]
        lines += [f"  {event['reason']}" if event["kind"] == "own settings" else
                  f"  fallback ({event['kind']}) at {event['at_iteration']}: {event['reason']}"
                  for event in self.data["fallback"]]
        for name, other in self.data.get("compare", {}).items():
            lines.append(f"  {name}: {'converged' if other['converged'] else 'not converged'} after "
                         f"{other['iterations']} iterations, {other['wall_time_s']:.1f} s; "
                         f"controller/{name}: iterations {other['ratio_iterations']:.3f}, "
                         f"wall time {other['ratio_wall_time']:.3f}")
            if "agreement" in other:
                lines.append(f"    {summary_line(name, other['agreement'])}")
            if "spread" in other:
                lines.append(f"    {spread_line(other['spread'], self.data['settings']['criterion'])}")
        return "\n".join(lines)


def _verdict(result: dict[str, Any]) -> str:
    """Converged and confirmed at a fixed relaxation, converged (by the case's own function object, or
    by the case's own run that replaced the controlled one: nothing was confirmed), or not converged."""
    if result["outcome"] == SETTLED:
        return "the answer settled within the tolerance; its criterion NOT met"
    if result["outcome"] == "oscillating":
        return "the answer oscillates about a steady mean; its error is half its range"
    if not result["converged"]:
        return "NOT converged"
    return "converged, confirmed" if str(result.get("converged_by")).endswith("confirmed") else "converged"


def _criterion_line(data: dict[str, Any]) -> list[str]:
    """The criterion, where it came from, what ended the run (jaxsimrl.apps.foam.solve.criterion), where it
    started."""
    settings, result = data["settings"], data["result"]
    if "criterion_from" not in settings:
        return []
    line = f"  criterion {describe(settings['criterion'], settings['criterion_from'])}"
    if result.get("converged_by"):
        line += f"; converged by {result['converged_by']}"
    if settings.get("started_from"):
        line += f"; started from {settings['started_from']}"
    return [line]


def _percent(fraction: float | None) -> str:
    return "not measured (the result is a plain run of the case)" if fraction is None else \
        f"{100 * fraction:.1f} %"


def write_status(out: Path, status: str, case: Path, error: str = "") -> None:
    """solve.json before (or instead of) the report: what the directory holds (``error``: why it failed,
    or for "interrupted" how it was stopped)."""
    holds = {"incomplete": "a solve in progress or killed: no result yet; the case files may be partial",
             "interrupted": f"a solve {error or 'interrupted'} before its end: no result; every solver it "
                            f"started was stopped", "failed": f"no result: {error}"}[status]
    atomic_write_json(out / SOLVE_JSON, {"status": status, "case": str(case), "out": str(out),
                                         "holds": holds, "time_utc": _now()})


def residual_history(history: list[dict[str, float]], fields: list[str]) -> dict[str, list[float | None]]:
    """{field: one initial residual per iteration (vector fields: the largest component)}."""
    return {name: [field_residual(row, name) for row in history] for name in fields}


def build_report(case: Path, out: Path, controller: Any, cfg: Any, run: Any, rescue: Any,
                 time_name: str | None, wall: float, comparisons: dict[str, Any],
                 episode: Path, observed: dict[str, str] | None = None) -> SolveReport:
    """Everything solve.json holds (see the module docstring); ``observed``: {the policy's observed
    field: the case field that stands for it} (jaxsimrl.apps.foam.solve.fields), None if it observes none."""
    fields = list(cfg.convergence)
    parser = LogParser("", "")
    log = episode / "log.simpleFoam"
    if log.is_file():
        parser.feed(log.read_bytes())
        parser.finish()
    record = run.record  # foam_bridge's EpisodeRecord; None when the episode could not report one
    busy = run.wall_time_s if record is None else float(record.wall_time_s) - float(record.solver_idle_s)
    cpu = parser.execution_time if record is None else float(record.solver_time_s)
    iterations = run.iterations
    if rescue is not None:
        busy, cpu = busy + rescue.wall_time_s, cpu + rescue.cpu_time_s
        iterations += rescue.iterations
    converged = run.outcome == "converged" if rescue is None else rescue.converged
    rescued = "converged" if rescue is not None and rescue.converged else "not converged"
    result = {"outcome": run.outcome if rescue is None else rescued,
              "converged": converged, "iterations": iterations, "controlled_iterations": run.iterations,
              "wall_time_s": wall, "solver_cpu_time_s": cpu, "solver_busy_s": busy,
              # a fallback rerun may have overlapped the controlled run (--compare): no overhead figure then
              "overhead_fraction": max(wall - busy, 0.0) / wall if wall > 0 and rescue is None else None,
              "fields_from": _fields_from(run, rescue),
              "time_directory": time_name, "cause": run.cause}
    data = {"status": "complete", "case": str(case), "out": str(out), "time_utc": _now(),
            "cores": os.cpu_count(), "controller": controller.provenance,
            "settings": {"criterion": dict(cfg.convergence), "confirm_alpha_u": cfg.confirm_alpha_u,
                         # the turbulence fields' check factor, where the controller sets alpha_t
                         "confirm_alpha_t": (cfg.turbulence_check_factor
                                             if cfg.relax_k_omega == K_OMEGA_ACTION else None),
                         "action_low": list(cfg.action_low), "action_high": list(cfg.action_high),
                         "action_pivot": None if cfg.action_pivot is None else list(cfg.action_pivot),
                         "action_radius": cfg.action_radius,
                         "interval": cfg.interval, "state_interval": cfg.state_interval,
                         "max_iterations": cfg.max_iterations,
                         "observed_fields": observed},
            "result": result, "fallback": run.events, "steps": run.steps,
            "confirmations": (record.confirmations if record is not None else None) or [],
            "residuals": {"controlled": residual_history(parser.history, fields)}}
    if rescue is not None:
        own_label = "own" if run.outcome == "not run" else "fallback_rerun"
        data["residuals"][own_label] = residual_history(rescue.history, fields)
        answer = getattr(rescue, "answer", None)
        result.update(answer_result(answer, converged, rescue.history, dict(cfg.convergence)))
        if answer is not None:
            data["answer"] = answer
    data["compare"] = {name: _comparison(other, result) for name, other in comparisons.items()}
    for name, other in comparisons.items():
        data["residuals"][name] = residual_history(other.history, fields)
    return SolveReport(data)


def _fields_from(run: Any, rescue: Any) -> str:
    """Who set the factors of the run whose fields ``out`` holds."""
    if rescue is not None and run.outcome == "not run":
        default = any(event["kind"] == "own settings" for event in run.events)
        return f"the case's own settings ({'the default' if default else 'the controller does not apply'})"
    if rescue is not None:
        return "the case's own settings (fallback rerun)"
    switched = [event["at_iteration"] for event in run.events if event["kind"] == "watchdog"]
    if switched:
        return f"the controller, then the case's own factors from iteration {switched[0]} (watchdog)"
    return "the controller"


def _ratio(a: float, b: float) -> float:
    return a / b if b else float("nan")


def _comparison(other: Any, result: dict[str, Any]) -> dict[str, Any]:
    ratio = _ratio
    return {"case": other.case, "converged": other.converged, "iterations": other.iterations,
            "wall_time_s": other.wall_time_s, "solver_cpu_time_s": other.cpu_time_s, "error": other.error,
            "ratio_iterations": ratio(result["iterations"], other.iterations),
            "ratio_wall_time": ratio(result["wall_time_s"], other.wall_time_s),
            "ratio_solver_cpu_time": ratio(result["solver_cpu_time_s"], other.cpu_time_s)}


def write_report(out: Path, report: SolveReport) -> None:
    """solve.png, then solve.json (last: status "complete" means everything is there)."""
    atomic_write_bytes(out / SOLVE_PNG, plot_png(report.data))
    atomic_write_json(out / SOLVE_JSON, report.data)


def preload_plotting() -> None:
    """Import matplotlib (~1 s) ahead of :func:`plot_png`, e.g. in a thread while the solver runs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401


def plot_png(data: dict[str, Any]) -> bytes:
    """Residual histories (log scale), then the factors the controller used (where one acted) and the
    answer monitor's estimated errors (where it watched), as PNG bytes."""
    import io

    preload_plotting()
    import matplotlib.pyplot as plt

    answer = (data.get("answer") or {}).get("history")
    panels = 1 + bool(data["steps"]) + bool(answer)
    figure, axes = plt.subplots(panels, 1, figsize=(8, 3.5 + 2.2 * panels), sharex=True,
                                height_ratios=(2, *([1] * (panels - 1))), squeeze=False)
    top, rest = axes[0][0], [row[0] for row in axes[1:]]
    _draw_residuals(top, data)
    if data["steps"]:
        _draw_factors(rest.pop(0), data)
    if answer:
        _draw_answer(rest.pop(0), data["answer"], data["result"])
    axes[-1][0].set_xlabel("SIMPLE iteration")
    buffer = io.BytesIO()
    figure.tight_layout()
    figure.savefig(buffer, format="png", dpi=90)
    plt.close(figure)
    return buffer.getvalue()


def _draw_residuals(axis: Any, data: dict[str, Any]) -> None:
    colours = {name: f"C{index}" for index, name in enumerate(data["settings"]["criterion"])}
    for run, curves in data["residuals"].items():
        style = "-" if run in ("controlled", "own") else "--"
        for name, values in curves.items():
            points = [(i + 1, v) for i, v in enumerate(values) if v is not None and v > 0]
            if points:
                axis.semilogy(*zip(*points, strict=True), style, lw=1, color=colours.get(name),
                              label=f"{name} ({run})")
    for threshold in data["settings"]["criterion"].values():
        axis.axhline(threshold, color="grey", lw=0.5, ls=":")
    axis.set_ylabel("initial residual")
    axis.legend(fontsize=7, ncol=2)
    axis.set_title(f"jaxsimrl solve: {Path(data['case']).name}")


def _draw_factors(axis: Any, data: dict[str, Any]) -> None:
    for index in range(max((len(step["action"]) for step in data["steps"]), default=0)):
        xs, ys = [], []
        for step in data["steps"]:
            xs += [step["from_iteration"], step.get("to_iteration", step["from_iteration"])]
            ys += [step["action"][index]] * 2
        label = ("alpha_u", "alpha_p", "alpha_t")[index] if index < 3 else str(index)
        axis.plot(xs, ys, lw=1.2, label=label)
    for event in data["fallback"]:
        axis.axvline(event["at_iteration"], color="red", lw=0.8, ls="--")
    axis.set_ylabel("factor")
    axis.legend(fontsize=7)


#: Function-object values drawn in solve.png beside the fields: the largest errors at the end.
DRAWN_VALUES = 6


def _draw_answer(axis: Any, answer: dict[str, Any], result: dict[str, Any]) -> None:
    """Each quantity's estimated error at every check (fields solid, the function-object values with the
    largest final errors dashed), the tolerance, and where the run stopped."""
    history = answer["history"]
    final = {k: v for k, v in (answer.get("iterative_error") or {}).items() if v is not None}
    fields = [name for name in final if "/" not in name]
    values = sorted((n for n in final if "/" in n), key=lambda n: -final[n])[:DRAWN_VALUES]
    for index, name in enumerate([*fields, *values]):
        points = [(entry["iteration"], entry["errors"].get(name)) for entry in history]
        points = [(it, e) for it, e in points if e is not None and e > 0]
        if points:
            axis.semilogy(*zip(*points, strict=True), "-" if name in fields else "--", lw=1,
                          color=f"C{index % 10}", label=name if len(name) < 40 else name[:37] + "...")
    axis.axhline(answer["tolerance"], color="black", lw=0.8, ls=":", label="tolerance")
    axis.axvline(result["iterations"], color="red", lw=0.8, ls="--")
    axis.set_ylabel("estimated error")
    axis.set_title(f"the answer: {result['outcome']} at {result['iterations']}", fontsize=9)
    axis.legend(fontsize=6, ncol=2)


def _now() -> str:
    return datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
