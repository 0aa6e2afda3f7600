"""The fleet table: one row per robot (points, uncompensated and compensated error on its
held-out rows, what moved, warnings, why it failed) as Markdown, CSV or HTML."""
from __future__ import annotations

import csv
import html
import io

__all__ = ["COLUMNS", "fleet_table"]

COLUMNS = ["robot", "points", "uncomp. mean mm", "uncomp. max mm", "comp. mean mm", "comp. max mm",
           "moved parameters", "warnings", "failure"]


def _row(r: dict) -> list[str]:
    f = lambda v: "" if v is None else f"{v:.3f}"  # noqa: E731
    return [r["name"] + (" (unchanged)" if r.get("skipped") else ""), "" if r.get("points") is None else str(r["points"]),
            f(r.get("unc_mean")), f(r.get("unc_max")), f(r.get("comp_mean")), f(r.get("comp_max")),
            ", ".join(r.get("moved") or []), "; ".join(r.get("warnings") or []), r.get("error") or ""]


def fleet_table(results: list[dict], fmt: str = "md") -> str:
    """The fleet table as Markdown (``md``), ``csv`` or ``html``."""
    rows = [_row(r) for r in results]
    if fmt == "csv":
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerows([COLUMNS, *rows])
        return buf.getvalue()
    if fmt == "html":
        cell = lambda tag, v: f"<{tag}>{html.escape(v)}</{tag}>"  # noqa: E731
        body = "\n".join("<tr>" + "".join(cell("td", v) for v in row) + "</tr>" for row in rows)
        return f"<table>\n<tr>{''.join(cell('th', c) for c in COLUMNS)}</tr>\n{body}\n</table>\n"
    esc = lambda v: v.replace("|", "\\|").replace("\n", " ")  # noqa: E731
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(esc(v) for v in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"
