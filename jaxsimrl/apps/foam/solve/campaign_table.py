"""What a solve campaign reports (jaxsimrl.apps.foam.solve.campaign): one row per finished case, the table
OUT/campaign.csv and the plot OUT/campaign.png.

A row is built from what the case's solve wrote (its solve.json), so the rows of cases finished in an
earlier, killed campaign are rebuilt alike on ``--resume``; a case whose solve raised has a row of its
own, status "failed" and the cause.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from jaxsimrl.apps.foam.solve.answer import OSCILLATING, SETTLED, SUCCESS
from jaxsimrl.apps.foam.solve.report import preload_plotting
from jaxsimrl.runs.atomic import atomic_write_bytes, atomic_write_text

CAMPAIGN_CSV = "campaign.csv"
CAMPAIGN_PNG = "campaign.png"
#: Columns of campaign.csv; the own run's (``OWN_COLUMNS``) only with --compare.
COLUMNS = ("case", "out", "status", "iterations", "wall_s", "iterative_error", "controller", "cause")
OWN_COLUMNS = ("own_iterations", "ratio_iterations", "own_wall_s", "ratio_wall")
#: status of a case whose solve ended with a result / raised (bad case, solver failure, lost workers);
#: SETTLED and OSCILLATING: its own run stopped on its answer (jaxsimrl.apps.foam.solve.answer).
CONVERGED, NOT_CONVERGED, FAILED = "converged", "not converged", "failed"


def row_of(case: Path, out: Path, data: Mapping[str, Any]) -> dict[str, Any]:
    """The row of a finished solve from its solve.json ``data`` (status "complete")."""
    result = data["result"]
    status = CONVERGED if result["converged"] else NOT_CONVERGED
    status = result["outcome"] if result.get("outcome") in (SETTLED, OSCILLATING) else status
    errors = [v for v in (result.get("iterative_error") or {}).values() if v is not None]
    row: dict[str, Any] = {"case": str(case), "out": out.name, "status": status,
                           "iterations": int(result["iterations"]),
                           "wall_s": round(float(result["wall_time_s"]), 2),
                           "iterative_error": f"{max(errors):.1e}" if errors else "",
                           "controller": controller_label(data.get("controller") or {}),
                           "cause": "" if status in SUCCESS else str(result.get("cause") or "")}
    own = (data.get("compare") or {}).get("own")
    if own is not None:
        row.update(own_iterations=int(own["iterations"]), ratio_iterations=_rounded(own["ratio_iterations"]),
                   own_wall_s=round(float(own["wall_time_s"]), 2),
                   ratio_wall=_rounded(own["ratio_wall_time"]))
    return row


def failed_row(case: Path, out: Path, cause: str) -> dict[str, Any]:
    """The row of a case whose solve gave no result."""
    return {"case": str(case), "out": out.name, "status": FAILED, "iterations": "", "wall_s": "",
            "controller": "", "cause": " ".join(cause.split())}


def controller_label(provenance: Mapping[str, Any]) -> str:
    """What acted, in a word: the rule's name, "shipped" (the default controller) or the run directory."""
    if "rule" in provenance:
        return str(provenance["rule"])
    if provenance.get("default"):
        return "shipped"
    where = provenance.get("path", "")
    return f"{where} (checkpoint {provenance['checkpoint']})" if "checkpoint" in provenance else str(where)


def _rounded(value: Any) -> Any:
    return round(float(value), 4) if value is not None and math.isfinite(float(value)) else ""


def write_table(out: Path, rows: Sequence[Mapping[str, Any]], compare: bool) -> None:
    """OUT/campaign.csv, rewritten whole and atomically: a reader (or a kill -9) never sees half a table."""
    columns = (*COLUMNS[:6], *(OWN_COLUMNS if compare else ()), *COLUMNS[6:])
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    atomic_write_text(out / CAMPAIGN_CSV, buffer.getvalue())


def write_plot(out: Path, rows: Sequence[Mapping[str, Any]], compare: bool) -> None:
    """OUT/campaign.png: iterations and wall seconds per case, the controller's bar beside the case's own
    settings' where --compare; a failed case has no bar and says so."""
    preload_plotting()  # matplotlib with the Agg backend: no display needed
    import matplotlib.pyplot as plt

    names = [str(row["out"]).removesuffix(".solved") for row in rows]
    width = 0.4 if compare else 0.7
    figure, axes = plt.subplots(2, 1, figsize=(max(6.0, 0.7 * len(rows) + 2), 6.5), sharex=True)
    for axis, (mine, own, label) in zip(axes, (("iterations", "own_iterations", "SIMPLE iterations"),
                                               ("wall_s", "own_wall_s", "wall time (s)")), strict=True):
        shift = -width / 2 if compare else 0.0
        axis.bar([i + shift for i in range(len(rows))], [_number(row.get(mine)) for row in rows], width,
                 label="controller", color="C0")
        if compare:
            axis.bar([i + width / 2 for i in range(len(rows))], [_number(row.get(own)) for row in rows],
                     width, label="own settings", color="C1")
            axis.legend(fontsize=8)
        for i, row in enumerate(rows):
            if row["status"] == FAILED:
                axis.text(i, 0, "failed", rotation=90, ha="center", va="bottom", color="red", fontsize=8)
        axis.set_ylabel(label)
    axes[0].set_title(f"jaxsimrl solve campaign: {len(rows)} cases")
    axes[1].set_xticks(range(len(rows)), names, rotation=45, ha="right", fontsize=8)
    figure.tight_layout()
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=90)
    plt.close(figure)
    atomic_write_bytes(out / CAMPAIGN_PNG, buffer.getvalue())


def _number(value: Any) -> float:
    """A bar's height: 0 for an empty cell (a failed case, no own run)."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return 0.0


def finished_line(row: Mapping[str, Any]) -> str:
    """How a finished case ended, in a line (jaxsimrl.cli.progress puts the count before it)."""
    head = f"{row['out']}: {row['status']}"
    if row["status"] == FAILED:
        return f"{head}: {row['cause']}"
    text = f"{head} after {row['iterations']} iterations, {float(row['wall_s']):.1f} s"
    if row.get("iterative_error"):
        text += f", iterative error {row['iterative_error']}"
    if row.get("own_iterations", "") != "":
        text += f"; own {row['own_iterations']} iterations (x{row['ratio_iterations']})"
    return text + (f"; {row['cause']}" if row["cause"] else "")
