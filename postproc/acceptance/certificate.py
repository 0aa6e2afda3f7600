"""The calibration certificate: one page a customer files when a cell is signed off.

It states what was tested (robot, tool, measurement device, the measured files and their
sha256, the date of issue), the ISO 9283 pose figures before and after compensation, the
method's Table 2 of the positioning-error norms, the identified parameters that moved and a
plot. Anything the inputs do not record is printed as "not recorded", never guessed.

One list of blocks (headings, paragraphs, tables, images) is rendered twice: as Markdown
(``certificate.md`` beside ``certificate.png``) and as one self-contained HTML page
(``certificate.html``: inline CSS, the PNG inlined as base64, no external reference, so it
opens offline). ``iso9283.json`` holds every number. matplotlib is imported only to plot.
"""
from __future__ import annotations

import base64
import datetime as _dt
import html
import json
import math
from pathlib import Path

import numpy as np

from ..core.diagnostics import P107, PostprocError
from ..core.stats import table2
from ..model.identified import UNIT_SCALE, PARAMETER_NAMES
from .iso9283 import IsoResult, iso_summary
from .report import identifiability_lines, model_card

__all__ = ["NOT_RECORDED", "certificate_blocks", "render_markdown", "render_html", "write_certificate"]

NOT_RECORDED = "not recorded"
PLOT = "certificate.png"
MAX_POSE_ROWS = 12  # the page lists this many poses (worst AP first when there are more); all in iso9283.json


def _card_value(card: dict, key: str):
    value = card.get(key)
    if isinstance(value, dict):
        value = value.get("name")
    return value if value not in (None, "") else None


UNIT_SUFFIXES = ("_deg", "_mm", "_rad", "_mm_per_n", "_deg_per_nm")


# an identified parameter "moved" when it lies more than this many of its std from nominal (0),
# as train --update's table calls a change significant (training/update.MOVED_SIGMAS)
MOVED_SIGMAS = 3.0
MAX_PARAMETER_ROWS = 24  # the page lists this many (most significant first); all in the model card


def identified_table(identified: dict) -> list[tuple[str, int, str, float, float | None, str]]:
    """Every identified parameter of the card's ``identified`` (training.kinematic.Layout's order:
    the groups of ``parameters``, then the gear-ripple amplitudes of ``ripple`` /
    ``ripple_amplitudes``): (group, index in the group, name, value, std, unit of the value's
    display). The std is the posterior one (``parameter_posterior_std``, what the data knows of
    the value) where the card has it, else ``parameter_std``; None where neither has it. The one
    list the certificate counts and lists, as the identifiability counts the layout's parameters."""
    stds = identified.get("parameter_posterior_std") or identified.get("parameter_std") or {}
    out = []
    for group, values in identified["parameters"].items():
        names, units = PARAMETER_NAMES.get(group, (None, [""]))
        std = stds.get(group) or [None] * len(values)
        for k, (v, s) in enumerate(zip(values, std)):
            name = f"{group}.{names[k]}" if names and k < len(names) else f"{group}[{k}]"
            out.append((group, k, name, float(v), s, units[k % len(units)]))
    amplitudes = [float(v) for pair in identified.get("ripple_amplitudes") or [] for v in pair]
    orders = identified.get("ripple") or []
    std = stds.get("ripple") or [None] * len(amplitudes)
    for k, (v, s) in enumerate(zip(amplitudes, std)):
        joint, order = orders[k // 2] if k // 2 < len(orders) else ("?", "?")
        out.append(("ripple", k, f"ripple.A{joint}x{order}.{'sin' if k % 2 == 0 else 'cos'}", v, s, "deg"))
    return out


def _parameter_rows(identified: dict) -> tuple[list[list[str]], str]:
    """(rows, note) of the identified parameters (:func:`identified_table`) that moved more than
    MOVED_SIGMAS of their std from nominal, most significant first; those the data does not
    determine alone (``identifiability.undetermined``) are counted, not listed: the prior splits
    their shared effect, their std says nothing of their value."""
    undetermined = (identified.get("identifiability") or {}).get("undetermined") or {}
    table = identified_table(identified)
    found, apart, untested = [], 0, 0
    for group, k, name, v, s, unit in table:
        if k in undetermined.get(group, ()):
            apart += 1
            continue
        if s is None:  # (an older card: no std of the ripple amplitudes)
            untested += 1
            continue
        scale = UNIT_SCALE.get(unit, 1.0)
        z = abs(v) / s if s else (math.inf if v else 0.0)
        if z > MOVED_SIGMAS:
            found.append((z, [name, f"{v * scale:.5g} {unit}", f"{s * scale:.2g} {unit}"]))
    found.sort(key=lambda f: -f[0])
    note = (f"{len(found)} of {len(table)} identified parameters moved more than {MOVED_SIGMAS:g}σ from nominal"
            + (f" (the {MAX_PARAMETER_ROWS} most significant listed)" if len(found) > MAX_PARAMETER_ROWS else "")
            + ("; σ: what the data (and the weak prior) knows of the value, the posterior std"
               if identified.get("parameter_posterior_std") else
               "; σ is the spread of the estimate over repeated measurements of the same poses") + "."
            + (f" {apart} of them the data does not determine alone (Identifiability) are not listed: it fixes "
               "their combined effect with others, the weak prior splits it among them." if apart else "")
            + (f" {untested} without a std in the model card are not tested." if untested else "")
            + " Every value and std is in the model card (identified.parameters, ripple_amplitudes, "
              "parameter_posterior_std).")
    return [row for _, row in found[:MAX_PARAMETER_ROWS]], note


def _moved_parameters(card: dict) -> tuple[list[list[str]], str | None]:
    """Rows (parameter, value, uncertainty) of the identified parameters that moved from their
    nominal value, and a note. From the card's ``identified.parameters`` and ``parameter_std``
    (hybrid / kinematic models; see :func:`_parameter_rows`); older cards: the non-zero numbers
    of ``identified`` whose key names a unit (``backlash_deg`` …; orders, branches and flags
    are not parameters), with ``identified_std`` (same keys) where the card has it."""
    rows = []
    identified = card.get("identified") or {}
    note = None
    if isinstance(identified.get("parameters"), dict):
        rows, note = _parameter_rows(identified)
        identified = {}  # (its ripple orders are parameters of the table above)
    uncertainty = card.get("identified_std") or {}
    for key, value in identified.items():
        if not key.endswith(UNIT_SUFFIXES) or not _numeric(value):
            continue
        values = np.asarray(value, dtype=float).ravel()
        if not np.any(values != 0):
            continue
        std = uncertainty.get(key)
        shown = ", ".join(f"{v:.5g}" for v in values)
        rows.append([key, shown, ", ".join(f"{v:.2g}" for v in np.ravel(std)) if std is not None else NOT_RECORDED])
    if "ripple" in identified:
        rows.append(["gear-ripple orders (joint, harmonic)",
                     "; ".join(f"A{j} ×{h}" for j, h in identified["ripple"]), "–"])
    return rows, note


def _numeric(value) -> bool:
    try:
        return np.asarray(value, dtype=float).size > 0
    except (TypeError, ValueError):
        return False


def _f(v, digits: int = 3) -> str:
    return "–" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.{digits}f}"


def certificate_blocks(result: IsoResult, card: dict | None = None, date: str | None = None,
                       plot: str | None = PLOT) -> list[tuple]:
    """The certificate's content as blocks: ("h1"|"h2"|"p"|"notice", text), ("table", header, rows),
    ("img", file, caption). Simulated measurements or a demonstration model: said in the title,
    a notice before everything else and the first row of the table."""
    card = card or {}
    meta = result.meta or {}
    date = date or _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    b, a = result.before, result.after
    robot = _card_value(card, "robot") or meta.get("robot")
    tool = _card_value(card, "tool") or meta.get("tool")
    device = meta.get("device") or meta.get("tracker")
    identity = [
        ["robot", robot or NOT_RECORDED],
        ["tool", tool or NOT_RECORDED],
        ["measurement device", device or f"{NOT_RECORDED} (no '# device:' line in the measurement file)"],
        ["measured, before", f"{Path(result.source).name} — sha256 {result.source_sha256}"],
        ["measured, after", f"{Path(result.after_source).name} — sha256 {result.after_sha256}" if a is not None
         else "no measurement of the compensated program (before only)"],
        ["model", f"{card.get('name', '')} — sha256 {card.get('sha256', '')}" if card.get("sha256")
         else NOT_RECORDED],
        ["frame of the measurements", meta.get("frame", "base") + (f"; {meta['registration']}"
                                                                    if meta.get("registration") else "")],
        ["date of issue", date],
    ]
    # what this certificate is not: on its face, in its title and before anything else
    caveats = []
    if meta.get("simulated"):
        seed = f", robot seed {meta['robot_seed']}" if meta.get("robot_seed") else ""
        caveats.append(f"the measurements are simulated (postproc measure: the simulated {meta['simulated']}{seed}), "
                       "not taken on a robot")
    demo = card.get("demonstration")
    if isinstance(demo, dict):
        caveats.append(f"the model is a demonstration model of a simulated robot ({demo.get('robot', 'simulated')}), "
                       "not a calibration of this robot")
    title = "Calibration certificate — ISO 9283 pose test"
    if caveats:
        title += " — " + ("SIMULATED DATA" if meta.get("simulated") else "DEMONSTRATION MODEL")
        identity.insert(0, ["status", "; ".join(caveats)])
    blocks: list[tuple] = [("h1", title)]
    if caveats:
        blocks.append(("notice", "Not a certificate of a real robot: " + "; ".join(caveats) + "."))
    blocks.append(("table", ["", ""], identity))

    order = np.argsort(-b.ap, kind="stable")[:MAX_POSE_ROWS] if len(b) > MAX_POSE_ROWS else np.arange(len(b))
    header = ["pose", "n", "X, Y, Z (mm)", "AP before", "RP before"] + (["AP after", "RP after"] if a else [])
    rows = []
    for k in order:
        row = [b.name(k), str(b.n[k]), ", ".join(f"{v:.1f}" for v in b.command[k, :3]), _f(b.ap[k]), _f(b.rp[k])]
        if a is not None:
            row += [_f(a.ap[k]), _f(a.rp[k])]
        rows.append(row)
    summary = iso_summary(result)
    ob = summary["before"]["overall"]
    worst = ["all poses (worst)", f"{b.n.min()}–{b.n.max()}", "", _f(ob["AP_max"]), _f(ob["RP_max"])]
    if a is not None:
        oa = summary["after"]["overall"]
        worst += [_f(oa["AP_max"]), _f(oa["RP_max"])]
    rows.append(worst)
    shown = "" if len(order) == len(b) else f" The {len(order)} of {len(b)} poses with the largest AP before are listed."
    blocks += [("h2", "ISO 9283 pose accuracy (AP) and repeatability (RP), mm"), ("table", header, rows),
               ("p", "AP: distance of the barycentre of the attained positions from the command (ISO 9283:1998 "
                     "§7.2.1); RP = l̄ + 3·S_l (§7.2.2). n = cycles measured per pose." + shown)]
    if b.n.min() < 30:
        blocks.append(("p", f"Fewer than the standard's 30 cycles at {int((b.n < 30).sum())} of {len(b)} poses: "
                            "the standard's formulas, not a test to the standard."))
    if b.ap_abc is not None:
        o_rows = [[b.name(k)] + [_f(v, 4) for v in b.ap_abc[k]] + [_f(v, 4) for v in b.rp_abc[k]] for k in order]
        blocks += [("h2", "Orientation (deg, before)"),
                   ("table", ["pose", "APa", "APb", "APc", "RPa ±", "RPb ±", "RPc ±"], o_rows)]
    else:
        blocks.append(("p", "Orientation: " + NOT_RECORDED + " (no a_meas, b_meas, c_meas columns)."))

    t_before = table2(np.linalg.norm(result.deviation, axis=1))
    t_rows = [["before"] + [_f(t_before[k]) for k in ("max", "min", "mean", "std")]]
    if result.deviation_after is not None:
        t_after = table2(np.linalg.norm(result.deviation_after, axis=1))
        t_rows.append(["after, measured"] + [_f(t_after[k]) for k in ("max", "min", "mean", "std")])
    blocks += [("h2", "Table 2: positioning-error norm over all rows, mm"),
               ("table", ["", "max", "min", "mean", "std"], t_rows)]

    moved, note = _moved_parameters(card)
    blocks.append(("h2", "Identified parameters that moved"))
    if moved:
        blocks.append(("table", ["parameter", "identified value", "uncertainty (1σ)"], moved))
        if note:
            blocks.append(("p", note))
        elif not card.get("identified_std"):
            blocks.append(("p", "Uncertainty: " + NOT_RECORDED + " in the model card."))
        if card.get("structure"):
            blocks.append(("p", f"Model structure: {card['structure']}; the model card records only the values "
                                "listed here, the others are " + NOT_RECORDED + "."))
    else:
        blocks.append(("p", NOT_RECORDED + (" (no model given)" if not card else " (the model card lists none)")))
    ident = identifiability_lines(card)
    if ident:
        blocks += [("h2", "Identifiability"), *(("p", line) for line in ident)]
    sure = card.get("uncertainty")
    if isinstance(sure, dict) and "max_std_mm" in sure:
        blocks.append(("p", f"Per target the model states its own std (ONNX output error_std); compensate warns "
                            f"(P336) where it exceeds {sure['max_std_mm']:g} mm ({sure.get('max_std_rule', 'the card')})."))
    if plot:
        blocks.append(("img", plot, "AP and RP per pose, before and after compensation"))
    return blocks


def _md_cell(text: str) -> str:
    return str(text).replace("|", "¦")


def render_markdown(blocks: list[tuple]) -> str:
    out: list[str] = []
    for block in blocks:
        kind = block[0]
        if kind == "h1":
            out += [f"# {block[1]}", ""]
        elif kind == "h2":
            out += [f"## {block[1]}", ""]
        elif kind == "p":
            out += [block[1], ""]
        elif kind == "notice":
            out += [f"> **{block[1]}**", ""]
        elif kind == "table":
            header, rows = block[1], block[2]
            out.append("| " + " | ".join(_md_cell(h) for h in header) + " |")
            out.append("|" + "|".join("---" for _ in header) + "|")
            out += ["| " + " | ".join(_md_cell(c) for c in row) + " |" for row in rows]
            out.append("")
        elif kind == "img":
            out += [f"![{block[2]}]({block[1]})", ""]
    return "\n".join(out)


CSS = """body{font-family:DejaVu Sans,Arial,sans-serif;max-width:1100px;margin:24px auto;color:#111;font-size:14px}
h1{font-size:22px;border-bottom:2px solid #333;padding-bottom:6px}h2{font-size:16px;margin-top:18px}
table{border-collapse:collapse;margin:6px 0}td,th{border:1px solid #bbb;padding:3px 8px;text-align:right}
td:first-child,th:first-child{text-align:left}table.kv td{text-align:left}img{max-width:100%}p{margin:6px 0}
p.notice{border:3px solid #b00;background:#fee;color:#700;font-weight:bold;padding:8px;font-size:16px}"""


def render_html(blocks: list[tuple], folder: Path) -> str:
    """One self-contained page: images from ``folder`` inlined as base64 data URIs."""
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           "<title>Calibration certificate</title>", f"<style>{CSS}</style></head><body>"]
    for block in blocks:
        kind = block[0]
        if kind in ("h1", "h2", "p"):
            out.append(f"<{kind}>{html.escape(block[1])}</{kind}>")
        elif kind == "notice":
            out.append(f'<p class="notice">{html.escape(block[1])}</p>')
        elif kind == "table":
            header, rows = block[1], block[2]
            out.append("<table>" if any(header) else '<table class="kv">')
            if any(header):
                out.append("<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in header) + "</tr>")
            out += ["<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in rows]
            out.append("</table>")
        elif kind == "img":
            data = base64.b64encode((folder / block[1]).read_bytes()).decode("ascii")
            out.append(f'<img alt="{html.escape(block[2])}" src="data:image/png;base64,{data}">')
    out.append("</body></html>")
    return "\n".join(out) + "\n"


def write_plot(result: IsoResult, path: Path, max_poses: int = 40) -> None:
    """AP and RP per pose, before and after (bars), 1400 × 560 px."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    b, a = result.before, result.after
    k = np.arange(min(len(b), max_poses))
    fig = Figure(figsize=(14, 5.6), layout="constrained")
    FigureCanvasAgg(fig)
    for i, (name, pick) in enumerate((("AP", lambda f: f.ap), ("RP", lambda f: f.rp))):
        ax = fig.add_subplot(1, 2, i + 1)
        width = 0.4 if a is not None else 0.8
        ax.bar(k - (width / 2 if a is not None else 0), pick(b)[k], width, label="before", color="tab:red")
        if a is not None:
            ax.bar(k + width / 2, pick(a)[k], width, label="after (measured)", color="tab:blue")
        ax.set_xticks(k, [b.name(j) for j in k], rotation=90 if len(k) > 10 else 0, fontsize=8)
        ax.set_ylabel(f"{name} (mm)")
        ax.set_title(f"pose {'accuracy' if name == 'AP' else 'repeatability'} {name} per pose"
                     + ("" if len(k) == len(b) else f" (first {len(k)} of {len(b)})"))
        top = np.nanmax(np.r_[pick(b)[k], pick(a)[k] if a is not None else []]) if len(k) else 1.0
        ax.set_ylim(0.0, 1.25 * top if np.isfinite(top) and top > 0 else 1.0)  # room for the legend above the bars
        ax.legend(loc="upper right", ncol=2)
        ax.grid(axis="y", alpha=0.3)
    fig.savefig(path, dpi=100, metadata={"Software": None})


def write_certificate(result: IsoResult, folder: str | Path, model=None, date: str | None = None) -> dict[str, Path]:
    """Write iso9283.json, certificate.png, certificate.md and certificate.html into ``folder``."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise PostprocError(f"cannot create the report folder: {exc.strerror}", str(folder), code=P107) from None
    card = model_card(model) if model is not None else {}
    numbers = iso_summary(result)
    (folder / "iso9283.json").write_text(json.dumps(numbers, indent=1) + "\n", encoding="utf-8")
    write_plot(result, folder / PLOT)
    blocks = certificate_blocks(result, card, date)
    (folder / "certificate.md").write_text(render_markdown(blocks), encoding="utf-8")
    (folder / "certificate.html").write_text(render_html(blocks, folder), encoding="utf-8")
    return {"iso9283_json": folder / "iso9283.json", "plot": folder / PLOT,
            "certificate_md": folder / "certificate.md", "certificate_html": folder / "certificate.html"}
