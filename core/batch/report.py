"""The study report of a batch: one HTML page in the session folder (``batch-report.html``) with a table
per take and a plot of the labelled share and the mean residual across takes (a PNG embedded in the
page, drawn with matplotlib's Agg backend: no display needed).

The table lists first the takes to open first: failed ones, then those with the lowest labelled
share, the most health warnings and the longest gap left.
"""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path
from typing import Any

from handmocap.core.session.files import write_file

REPORT_NAME = "batch-report.html"
COLUMNS = ("take", "status", "labelled %", "filled %", "longest gap (frames)", "residual mm", "warnings", "seconds",
           "reason")
#: take names on the plot's axis are shortened to this many characters (the table has them whole)
AXIS_NAME_CHARACTERS = 24


def _order(row: dict[str, Any]) -> tuple:
    """Sort key: failed first, then skipped/not run, then by labelled share, warnings and gap left."""
    status = {"failed": 0, "skipped": 1, "queued": 1}.get(row.get("status", ""), 2)
    return (status, row.get("labelled_share", 1.0), -row.get("health_count", 0), -row.get("longest_gap", 0))


def study_plot(rows: list[dict[str, Any]]) -> bytes:
    """PNG of the done takes (in session order): labelled share (bars, %) and mean residual (mm, dots)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    done = [row for row in rows if row.get("status") == "done"]
    figure = Figure(figsize=(9, 5.2 if done else 4.5), dpi=100)
    share_axes, residual_axes = figure.subplots(2, 1, sharex=True)
    positions = range(len(done))
    names = [_short(str(row.get("name") or row.get("take", ""))) for row in done]
    share_axes.bar(positions, [100 * row.get("labelled_share", 0.0) for row in done], color="#4a7fb5")
    share_axes.set_ylabel("labelled %")
    share_axes.set_ylim(0, 100)
    residuals = [row.get("mean_residual_mm") for row in done]
    residual_axes.plot([p for p, r in zip(positions, residuals, strict=True) if r is not None],
                       [r for r in residuals if r is not None], "o", color="#c0504d", markersize=3)
    residual_axes.set_ylabel("mean residual mm")
    residual_axes.set_xlabel("take (session order)")
    # one tick per take, named: not the -0.5 .. n-0.5 of a numeric axis
    residual_axes.set_xticks(list(positions))
    residual_axes.set_xticklabels(names, rotation=30 if len(done) <= 20 else 90, ha="right", fontsize=8)
    if done:
        residual_axes.set_xlim(-0.6, len(done) - 0.4)
    figure.suptitle(f"{len(done)} takes processed")
    figure.tight_layout()
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png")
    return buffer.getvalue()


def _short(name: str) -> str:
    """A take name shortened in the middle for the plot's axis."""
    if len(name) <= AXIS_NAME_CHARACTERS:
        return name
    half = (AXIS_NAME_CHARACTERS - 1) // 2
    return f"{name[:half]}…{name[-half:]}"


def _cell(row: dict[str, Any], column: str) -> str:
    value: Any
    if column == "take":
        value = f"{row.get('name', '')} ({row['take']})"
    elif column in ("labelled %", "filled %"):
        share = row.get("labelled_share" if column == "labelled %" else "filled_share")
        value = "" if share is None else f"{100 * share:.1f}"
    elif column == "residual mm":
        value = "" if row.get("mean_residual_mm") is None else f"{row['mean_residual_mm']:.2f}"
    elif column == "longest gap (frames)":
        value = row.get("longest_gap", "")
    elif column == "warnings":
        value = row.get("health_count", "")
        if row.get("health"):
            return f'<td title="{html.escape(chr(10).join(row["health"]))}">{value}</td>'
    else:
        value = row.get(column, "")
    return f"<td>{html.escape(str(value))}</td>"


def study_report_html(session_name: str, rows: list[dict[str, Any]]) -> str:
    """The report page of ``rows`` (one summary per take: ``take``, ``name``, ``status``, figures of
    :func:`core.batch.steps.review_figures`, ``seconds``, ``reason``)."""
    done = [row for row in rows if row.get("status") == "done"]
    failed = sum(1 for row in rows if row.get("status") == "failed")
    seconds = sum(row.get("seconds", 0.0) or 0.0 for row in done)
    shares = [row["labelled_share"] for row in done if row.get("labelled_share") is not None]
    summary = (f"{len(done)} of {len(rows)} takes done, {failed} failed; "
               f"median labelled share {100 * sorted(shares)[len(shares) // 2]:.1f} %; " if shares else
               f"{len(done)} of {len(rows)} takes done, {failed} failed; ") + f"{seconds:.0f} s of processing"
    image = base64.b64encode(study_plot(rows)).decode()
    body = "\n".join("<tr>" + "".join(_cell(row, column) for column in COLUMNS) + "</tr>"
                     for row in sorted(rows, key=_order))
    head = "".join(f"<th>{html.escape(column)}</th>" for column in COLUMNS)
    return (f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>Batch report: {html.escape(session_name)}"
            "</title><style>body{font-family:sans-serif} table{border-collapse:collapse} "
            "td,th{border:1px solid #bbb;padding:2px 6px;text-align:right} td:first-child{text-align:left}"
            "</style></head><body>"
            f"<h1>Batch report: {html.escape(session_name)}</h1><p>{html.escape(summary)}</p>"
            f"<p>Open first the takes at the top of the table (failed, least labelled, most warnings).</p>"
            f"<img alt='labelled share and residual per take' src='data:image/png;base64,{image}'>"
            f"<table><tr>{head}</tr>\n{body}</table></body></html>\n")


def write_study_report(folder: Path, session_name: str, rows: list[dict[str, Any]]) -> Path:
    """Write the report into the session ``folder`` (atomically); returns its path."""
    path = folder / REPORT_NAME
    write_file(folder, path, study_report_html(session_name, rows).encode("utf-8"))
    return path
