"""Accuracy reports: Table 2 figures, plots and the model card, from measured errors.

Input is a set of commanded poses with the positions the robot reached (a measurement CSV
``x,y,z,a,b,c,x_meas,y_meas,z_meas``). Before compensation the error is E = P − P_meas.
"After" is, by default, the first-order residual a compensation leaves, E − Ê(P) with Ê the
model's prediction. With the positions reached when the *compensated* commands were run —
a second measurement CSV of the compensated program (``postproc measure`` of the output of
``postproc compensate``, or the real cell's tracker), or ``x_after,y_after,z_after`` columns
in the first — it is the measured residual P − P_after.

Where the data has the measured orientation (``a_meas,b_meas,c_meas``) the report gives the
orientation error too (deg, the angle of commanded → measured): before, and after as the
model's first-order residual |r − r̂| (a model with ``rotation_error``) or as measured in the
``--after`` file (its a_meas..c_meas against the targets' A,B,C).

:func:`write_report` writes, into one folder: ``report.md`` (Table 2, the model card, the
figures), ``summary.json`` (the same numbers), ``series.csv`` and ``histogram.csv`` (every
number each plot shows, so that a reader or a test can check the plots) and three PNGs.
matplotlib is imported only in :func:`make_figures` / :func:`write_plots`, with the Agg canvas
(no display).
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.diagnostics import P107, P305, P500, P501, P502, P503, PostprocError
from ..core.stats import table2
from ..model.compensator import Compensator

__all__ = [
    "ReportData",
    "read_report_data",
    "table2",
    "histogram",
    "write_series",
    "write_plots",
    "make_figures",
    "write_report",
    "FIGURES",
]

TRAINED_ON = ("these rows trained the model (the file's sha256 is the model card's data_sha256): \"after\" is "
              "how well it fits its own training data, not its accuracy on new poses; report on rows it has not seen")
AFTER_COLUMNS = ("x_after", "y_after", "z_after")
FIGURES = {
    "histogram": "error_histogram.png",
    "vectors": "error_vectors.png",
    "predicted": "predicted_vs_measured.png",
}
BINS = 30
MIN_WIDTH_PX = 1200  # every figure, at write_plots' default dpi
MAX_ARROWS = 400  # more arrows than this hide each other in a 3-D quiver


@dataclass
class ReportData:
    """Errors at measured poses; ``after`` is what is left with compensation ([N, 3] mm)."""

    poses: np.ndarray  # [N, 6] commanded X,Y,Z,A,B,C (robot base frame)
    error: np.ndarray  # [N, 3] E = P − P_meas before compensation
    after: np.ndarray  # [N, 3] E − Ê (first order) or P − P_after (measured)
    predicted: np.ndarray | None = None  # [N, 3] Ê(P), when a model is given
    after_kind: str = "first-order"  # "first-order" | "measured"
    source: str = ""
    source_sha256: str = ""
    model_card: dict = field(default_factory=dict)  # the model's metadata + file, sha256
    orientation_corrected: bool = False  # the model corrects the orientation (rotation_error, compensate --orientation)
    outside_envelope: int = 0
    rotation_before: np.ndarray | None = None  # [N, 3] deg, commanded → measured (a_meas..c_meas)
    rotation_after: np.ndarray | None = None  # [N, 3] deg, r − r̂ (first order) or target → measured after
    error_std: np.ndarray | None = None  # [N] mm: the model's own std at each pose (output error_std)

    @property
    def trained_on(self) -> bool:
        """These rows are the model's own training data (the file's sha256 is the model card's
        ``data_sha256``): "after" then says how well it fits them, not how it does on new poses."""
        return bool(self.model_card) and self.model_card.get("data_sha256") == self.source_sha256

    @property
    def data_label(self) -> str:
        """On which data, for titles: the file, and whether the model was trained on it."""
        name = Path(self.source).name or "stdin"
        model = self.model_card.get("name", "") if self.model_card else ""
        text = f"{len(self)} poses of {name}" + (f", model {model}" if model else "")
        return text + (" (its own training data)" if self.trained_on else "")

    def __len__(self) -> int:
        return len(self.poses)

    @property
    def before_norm(self) -> np.ndarray:
        return np.linalg.norm(self.error, axis=1)

    @property
    def after_norm(self) -> np.ndarray:
        return np.linalg.norm(self.after, axis=1)


def _optional_columns(data: bytes, path: str, columns: tuple[str, ...]) -> tuple[list[str], list[int]] | None:
    """The lines of a measurement CSV and the header index of each of ``columns``; None if the
    header names none of them, P501 if it names only some."""
    text = data.removeprefix(b"\xef\xbb\xbf").decode("latin-1").splitlines()
    header_at = next(i for i, raw in enumerate(text) if raw.strip() and not raw.lstrip().startswith("#"))
    header = [h.strip().lower() for h in text[header_at].split(",")]
    present = [c in header for c in columns]
    if not any(present):
        return None
    if not all(present):
        raise PostprocError(f"give all of {','.join(columns)} or none", path, header_at + 1, 1, P501)
    return text, [header.index(c) for c in columns]


def _after_columns(data: bytes, lines: np.ndarray, path: str) -> np.ndarray | None:
    """``x_after,y_after,z_after`` of the rows at file ``lines``, if the header names them."""
    found = _optional_columns(data, path, AFTER_COLUMNS)
    if found is None:
        return None
    text, index = found
    out = np.empty((len(lines), 3))
    for row, line in enumerate(lines.tolist()):
        fields = text[line - 1].split(",")
        try:
            out[row] = [float(fields[i]) for i in index]
        except ValueError:
            out[row] = math.nan
        if not np.isfinite(out[row]).all():
            raise PostprocError("x_after/y_after/z_after is not a finite number", path, line, 1, P502)
    return out


def model_card(model: Compensator) -> dict:
    """The model's metadata (the model card) plus where it came from."""
    return {"file": str(model.path), "sha256": model.sha256, **model.metadata}


def _read(path: Path, repeats: bool = False):
    from ..measurements.csv import parse_measurements

    try:
        data = path.read_bytes()
    except OSError as exc:
        raise PostprocError(f"cannot read measurement file: {exc.strerror or exc}", str(path), code=P500) from None
    return data, parse_measurements(data, str(path), repeats)


# Rows of a re-measurement of the compensated program belong to the target rows if only X/Y/Z
# moved, by no more than a correction can be (compensate's bound is 5 mm by default), and A/B/C
# by no more than ``compensate --orientation`` turns them (a robot's orientation error: < 1°).
AFTER_POSITION_MM = 10.0
AFTER_ATTITUDE_DEG = 1.0


def _reached_after(path: Path, targets: np.ndarray, m=None) -> np.ndarray:
    """Positions reached in a measurement of the compensated program (``--after``), row by row;
    ``m``: that file's measurements if the caller has read them already. (Its measured
    orientation, if any: ``_after_rotation``.)"""
    from ..core.frames import rotation_error_deg

    if m is None:
        _, m = _read(path, repeats=True)  # row by row against the targets: a pose may repeat (ISO 9283 cycles)
    if len(m) != len(targets):
        raise PostprocError(f"{len(m)} rows, the measurement before compensation has {len(targets)}: measure the "
                            "compensated program in the same order", str(path), code=P503)
    moved = np.linalg.norm(m.poses[:, :3] - targets[:, :3], axis=1)
    turned = np.linalg.norm(rotation_error_deg(targets[:, 3:], m.poses[:, 3:]), axis=1)  # (near B = ±90° A and C alone swing)
    bad = np.flatnonzero((moved > AFTER_POSITION_MM) | (turned > AFTER_ATTITUDE_DEG))
    if len(bad):
        raise PostprocError(f"row does not belong to row {bad[0] + 1} before compensation (commanded pose "
                            f"{moved[bad[0]]:.3f} mm / {turned[bad[0]]:.3f}° away; only a correction changes "
                            "them): not the same program in the same order", str(path),
                            int(m.lines[bad[0]]), 1, P503)
    return m.measured


def read_report_data(path: str | Path, model: Compensator | None = None, after: str | Path | None = None) -> ReportData:
    """Read a measurement CSV and apply ``model``.

    "After" is measured if ``after`` is given (a measurement of the compensated program:
    same rows in the same order, commands = the compensated poses) or the CSV has
    ``x_after,y_after,z_after`` columns; else it is the first-order residual E − Ê, which
    needs ``model``."""
    path = Path(path)
    data, m = _read(path)
    error = m.poses[:, :3] - m.measured
    columns = _after_columns(data, m.lines, str(path))
    if after is not None and columns is not None:
        raise PostprocError("give the positions after compensation once: x_after.. columns or --after, not both",
                            str(path), code=P501)
    after_m = _read(Path(after), repeats=True)[1] if after is not None else None
    reached = _reached_after(Path(after), m.poses, after_m) if after is not None else columns
    rotation_before, rotation_after = _rotations(m, model, after_m, previous_of(m, model))
    # rows in visiting order: a model that takes previous_pose sees each row's predecessor
    previous = previous_of(m, model)
    error_std = None
    if model is not None and model.has_std:  # (the same run: onnxruntime adds only that output)
        predicted, error_std = model.predict(m.poses, previous, std=True)
    else:
        predicted = model.predict(m.poses, previous) if model is not None else None
    if predicted is not None and not np.isfinite(predicted).all():
        raise PostprocError("the model returns NaN or inf on these poses", str(model.path), code=P305)
    if reached is not None:
        after, kind = m.poses[:, :3] - reached, "measured"
    elif predicted is not None:
        after, kind = error - predicted, "first-order"
    else:
        raise PostprocError("nothing to compare: give --model (first-order residual E − Ê), --after (a measurement "
                            "of the compensated program) or x_after,y_after,z_after columns", str(path), code=P501)
    envelope = model.envelope if model is not None else None
    return ReportData(
        poses=m.poses,
        error=error,
        after=after,
        predicted=predicted,
        after_kind=kind,
        source=str(path),
        source_sha256=hashlib.sha256(data).hexdigest(),
        model_card=model_card(model) if model is not None else {},
        orientation_corrected=bool(model is not None and model.has_rotation),
        outside_envelope=int(envelope.outside(m.poses).sum()) if envelope is not None else 0,
        rotation_before=rotation_before,
        rotation_after=rotation_after,
        error_std=error_std,
    )


def previous_of(m, model: Compensator | None) -> np.ndarray | None:
    """The pose before each row (rows in visiting order) for a model that takes ``previous_pose``."""
    return np.vstack([m.poses[:1], m.poses[:-1]]) if model is not None and model.wants_previous else None


def _rotations(m, model: Compensator | None, after_m, previous) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Orientation errors [N, 3] deg before and after, where the data has them: before from the
    rows' a_meas..c_meas; after measured (``after_m``'s a_meas..c_meas against the targets' A,B,C)
    or the first-order residual r − r̂ of a model with ``rotation_error``; None where not known."""
    from ..core.frames import rotation_error_deg

    before = m.rotation_errors
    if after_m is not None:
        if after_m.orientation is None:
            return before, None
        return before, rotation_error_deg(m.poses[:, 3:6], after_m.orientation)
    if before is None or model is None or not model.has_rotation:
        return before, None
    return before, before - model.predict(m.poses, previous, rotation=True)[-1]


def histogram(data: ReportData, bins: int = BINS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(edges [bins+1], counts before [bins], counts after [bins]) on common bins from 0."""
    top = max(float(data.before_norm.max()), float(data.after_norm.max()), 1e-6)
    edges = np.linspace(0.0, top, bins + 1)
    return edges, np.histogram(data.before_norm, edges)[0], np.histogram(data.after_norm, edges)[0]


def write_series(data: ReportData, folder: Path) -> dict[str, Path]:
    """series.csv (per point: pose, E, Ê, after, norms) and histogram.csv (bins, counts)."""
    columns = {
        "x": data.poses[:, 0], "y": data.poses[:, 1], "z": data.poses[:, 2],
        "a": data.poses[:, 3], "b": data.poses[:, 4], "c": data.poses[:, 5],
        "ex": data.error[:, 0], "ey": data.error[:, 1], "ez": data.error[:, 2],
    }
    if data.predicted is not None:
        columns.update(ex_pred=data.predicted[:, 0], ey_pred=data.predicted[:, 1], ez_pred=data.predicted[:, 2])
    columns.update(ax=data.after[:, 0], ay=data.after[:, 1], az=data.after[:, 2],
                   norm_before=data.before_norm, norm_after=data.after_norm)
    series = folder / "series.csv"
    np.savetxt(series, np.column_stack(list(columns.values())), fmt="%.9g", delimiter=",",
               header=",".join(columns), comments="")
    edges, before, after = histogram(data)
    hist = folder / "histogram.csv"
    np.savetxt(hist, np.column_stack([edges[:-1], edges[1:], before, after]), fmt=["%.9g", "%.9g", "%d", "%d"],
               delimiter=",", header="bin_lo,bin_hi,count_before,count_after", comments="")
    return {"series": series, "histogram_csv": hist}


def vector_rows(n: int, limit: int = MAX_ARROWS) -> np.ndarray:
    """The rows drawn as arrows: all, or ``limit`` evenly spaced ones (summary.json lists them)."""
    return np.arange(n) if n <= limit else np.unique(np.linspace(0, n - 1, limit).round().astype(int))


def _vector_scale(data: ReportData) -> float:
    """Arrow magnification: the largest error drawn as 8 % of the measured box's diagonal."""
    span = float(np.linalg.norm(np.ptp(data.poses[:, :3], axis=0)))
    largest = max(float(data.before_norm.max()), 1e-9)
    return max(span, 1.0) * 0.08 / largest


DPI = 150


def write_plots(data: ReportData, folder: Path, dpi: int = DPI) -> dict[str, Path]:
    """The figures of :func:`make_figures` as PNGs (Agg canvas: no display needed)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    written: dict[str, Path] = {}
    for key, fig in make_figures(data).items():
        FigureCanvasAgg(fig)
        path = folder / FIGURES[key]
        fig.savefig(path, dpi=dpi, metadata={"Software": None})  # no version string: same data, same bytes
        written[key] = path
    return written


def make_figures(data: ReportData) -> dict:
    """The three figures (matplotlib Figures, by FIGURES key), at least ``MIN_WIDTH_PX`` wide
    at ``DPI``: axes labelled with units, a colour bar where colour carries a value, titles
    that say what is plotted and on which data."""
    from matplotlib import cm, colors
    from matplotlib.figure import Figure

    after_label = "after, |E − Ê| (first order)" if data.after_kind == "first-order" else "after, measured"
    made: dict[str, Figure] = {}

    def save(fig: Figure, key: str) -> None:
        made[key] = fig

    # 1. histogram of error norms, before and after, on common bins
    edges, before, after = histogram(data)
    fig = Figure(figsize=(8.4, 4.8), layout="constrained")
    ax = fig.add_subplot()
    width = edges[1] - edges[0]
    ax.bar(edges[:-1], before, width=width, align="edge", alpha=0.55, label="before, |E|", color="tab:red")
    ax.bar(edges[:-1], after, width=width, align="edge", alpha=0.55, label=after_label, color="tab:blue")
    for norms, color in ((data.before_norm, "tab:red"), (data.after_norm, "tab:blue")):
        ax.axvline(norms.mean(), color=color, linestyle="--", linewidth=1)
    ax.set_xlabel("positioning error norm |E| (mm); dashed lines: means")
    ax.set_ylabel("number of poses")
    ax.set_title(f"Positioning error before and after compensation\n{data.data_label}", fontsize=10)
    ax.legend(loc="upper right", framealpha=0.9)
    save(fig, "histogram")

    # 2. error vectors over the box, before and after, same magnification
    scale = _vector_scale(data)
    fig = Figure(figsize=(12.0, 5.6), layout="constrained")
    fig.suptitle(f"Error vectors at the commanded positions (arrows magnified ×{scale:.0f}), {data.data_label}",
                 fontsize=10)
    top = float(data.before_norm.max())
    norm = colors.Normalize(0.0, max(top, 1e-9))
    rows = vector_rows(len(data))
    p = data.poses[rows, :3]
    axes = []
    for k, (vectors, norms, label) in enumerate(((data.error, data.before_norm, "before, E"),
                                                 (data.after, data.after_norm, after_label))):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        # at the commanded position, along E: the direction from where the robot went to where it was sent
        ax.quiver(p[:, 0], p[:, 1], p[:, 2], *(vectors[rows] * scale).T, colors=_colormap(norms[rows] / max(top, 1e-9)),
                  linewidth=0.8, arrow_length_ratio=0.25)
        drawn = "" if len(rows) == len(data) else f", {len(rows)} of {len(data)} drawn"
        ax.set_title(f"{label}: mean {norms.mean():.3f} mm{drawn}", fontsize=9)
        ax.set_xlabel("X (mm)", fontsize=8)
        ax.set_ylabel("Y (mm)", fontsize=8)
        ax.set_zlabel("Z (mm)", fontsize=8, labelpad=6)
        ax.set_box_aspect(None, zoom=0.82)  # room for the Z label inside the axes' box
        ax.tick_params(labelsize=7)
        axes.append(ax)
    bar = fig.colorbar(cm.ScalarMappable(norm=norm, cmap="viridis"), ax=axes, shrink=0.7, pad=0.02)
    bar.set_label("error norm |E| (mm), one scale for both", fontsize=8)
    save(fig, "vectors")

    # 3. predicted vs measured error per axis (only with a model)
    if data.predicted is not None:
        fig = Figure(figsize=(12.0, 4.4), layout="constrained")
        fig.suptitle(f"Error predicted by the model against error measured, per axis; {data.data_label}", fontsize=10)
        for k, axis in enumerate("XYZ"):
            ax = fig.add_subplot(1, 3, k + 1)
            measured, predicted = data.error[:, k], data.predicted[:, k]
            lo, hi = min(measured.min(), predicted.min()), max(measured.max(), predicted.max())
            ax.plot([lo, hi], [lo, hi], color="grey", linewidth=1)
            ax.scatter(measured, predicted, s=6, alpha=0.7)
            ax.set_title(f"{axis}: R² {_r2(measured, predicted):.3f} (grey: predicted = measured)", fontsize=9)
            ax.set_xlabel(f"measured E{axis.lower()} (mm)", fontsize=8)
            ax.set_ylabel(f"predicted Ê{axis.lower()} (mm)", fontsize=8)
            ax.set_aspect("equal", adjustable="datalim")
        save(fig, "predicted")
    return made


def _colormap(values: np.ndarray) -> np.ndarray:
    from matplotlib import colormaps

    return colormaps["viridis"](np.clip(values, 0.0, 1.0))


def _r2(measured: np.ndarray, predicted: np.ndarray) -> float:
    ss = float(((measured - measured.mean()) ** 2).sum())
    return 1.0 - float(((measured - predicted) ** 2).sum()) / ss if ss > 0 else math.nan


def _card_rows(card: dict) -> list[str]:
    rows = []
    for key, value in card.items():
        text = value if isinstance(value, str) else json.dumps(value, separators=(", ", ": "))
        rows.append(f"| {key} | `{text.replace('|', '¦')}` |")
    return rows


def summary(data: ReportData) -> dict:
    """The numbers of the report (summary.json)."""
    before, after = table2(data.before_norm), table2(data.after_norm)
    return {
        "source": data.source,
        "source_sha256": data.source_sha256,
        "poses": len(data),
        "after": data.after_kind,
        "table2_mm": {"before": before, "after": after},
        "mean_reduction": 1.0 - after["mean"] / before["mean"] if before["mean"] else math.nan,
        "outside_envelope": data.outside_envelope,
        "orientation_deg": None if data.rotation_before is None else {
            "before": table2(np.linalg.norm(data.rotation_before, axis=1)),
            "after": None if data.rotation_after is None else table2(np.linalg.norm(data.rotation_after, axis=1)),
            "corrected": data.orientation_corrected},
        "trained_on_these_rows": data.trained_on,
        "vector_scale": _vector_scale(data),
        "vector_rows": vector_rows(len(data)).tolist(),
        "uncertainty": uncertainty_summary(data),
        "model": data.model_card,
    }


def uncertainty_summary(data: ReportData) -> dict | None:
    """How sure the model is at these poses (its output ``error_std``; None without it): the
    std's Table 2, the share of the residual coordinates (``after``, E − Ê) within 2·std (95 % if
    the std is calibrated; a measured "after" adds the robot's repeatability), the poses above
    the card's bound (compensate's P336) — and what the identification could separate."""
    if data.error_std is None:
        return None
    bound = (data.model_card.get("uncertainty") or {}).get("max_std_mm")
    return {
        "error_std_mm": table2(data.error_std),
        "two_sigma_coverage": float((np.abs(data.after) <= 2.0 * data.error_std[:, None]).mean()),
        "max_std_mm": bound,
        "above_max_std": int((data.error_std > bound).sum()) if bound is not None else None,
    }


def identifiability_lines(card: dict) -> list[str]:
    """The identification's identifiability from the model card (``identified.identifiability``:
    numerical rank, condition number of what the data separates, groups it cannot), in words;
    [] when the card has none (no physical model, or a re-calibration)."""
    ident = (card.get("identified") or {}).get("identifiability")
    if not isinstance(ident, dict) or "rank" not in ident:
        return []
    condition = ident.get("condition")
    lines = [f"Numerical rank {ident['rank']} of {ident.get('parameters', '?')} parameters"
             + (f"; condition number {condition:.3g} (of the directions the data separates)"
                if isinstance(condition, int | float) else "") + "."]
    apart = ident.get("unseparated") or []
    lines.append("Parameter groups the data cannot separate (the weak prior settles them, the data does not): "
                 + ("; ".join(" + ".join(g) for g in apart) if apart else "none") + ".")
    alone = ident.get("undetermined")
    if isinstance(alone, dict):
        count = sum(len(v) for v in alone.values())
        lines.append(f"{count} of {ident.get('parameters', '?')} parameters are not determined alone by the data"
                     + (f" ({', '.join(f'{g} {len(v)}' for g, v in alone.items())})" if count else "")
                     + ": their sum with others is, the model's predictions rest on that.")
    return lines


def write_markdown(data: ReportData, numbers: dict, figures: dict[str, Path], path: Path, title: str) -> None:
    before, after = numbers["table2_mm"]["before"], numbers["table2_mm"]["after"]
    after_label = ("after, \\|E − Ê\\| (first-order residual)" if data.after_kind == "first-order"
                   else "after, measured with compensation")
    lines = [
        f"# {title}",
        "",
        f"{len(data)} poses from `{Path(data.source).name}` (sha256 `{data.source_sha256[:12]}`)"
        + (f", model `{data.model_card.get('name', '')}` (sha256 `{str(data.model_card.get('sha256', ''))[:12]}`)"
           if data.model_card else "") + ".",
        "",
        "| positioning error (mm) | max | min | mean | std | p95 |",
        "|---|---:|---:|---:|---:|---:|",
        f"| before, \\|E\\| | {before['max']:.3f} | {before['min']:.3f} | {before['mean']:.3f} | {before['std']:.3f} "
        f"| {before['p95']:.3f} |",
        f"| {after_label} | {after['max']:.3f} | {after['min']:.3f} | {after['mean']:.3f} | {after['std']:.3f} "
        f"| {after['p95']:.3f} |",
        "",
        f"Mean error reduced by {100 * numbers['mean_reduction']:.1f} %. Std with ddof 1.",
    ]
    angles = numbers.get("orientation_deg")
    if angles is not None:
        lines += ["", "| orientation error (deg, angle) | max | min | mean | std |", "|---|---:|---:|---:|---:|"]
        for label, row in (("before", angles["before"]), (after_label, angles["after"])):
            if row is None:
                lines.append(f"| {label} | not known: the model has no rotation_error output / the after data no "
                             "a_meas,b_meas,c_meas | | | |")
            else:
                lines.append(f"| {label} | {row['max']:.4f} | {row['min']:.4f} | {row['mean']:.4f} | {row['std']:.4f} |")
        if not angles.get("corrected", True):
            lines += ["", "The orientation was not corrected: the model corrects the position only (a model with a "
                      "rotation_error output and `compensate --orientation` correct it too), so the orientation "
                      "error after is the robot's own."]
    if data.after_kind == "first-order":
        lines.append("\"After\" is E − Ê at the measured poses: what compensation leaves to first order, "
                     "not a measurement of the compensated robot.")
    if data.trained_on:
        lines.append(f"**{TRAINED_ON}**")
    if data.outside_envelope:
        lines.append(f"**{data.outside_envelope} of {len(data)} poses lie outside the model's training envelope.**")
    lines += [""]
    captions = {"histogram": "Error norms before and after", "vectors": "Error vectors over the measured box",
                "predicted": "Predicted vs measured error per axis"}
    for key, figure in figures.items():
        lines += [f"![{captions[key]}]({figure.name})", ""]
    sure = numbers.get("uncertainty")
    ident = identifiability_lines(data.model_card)
    if sure or ident:
        lines += ["## How sure the model is", ""]
    if sure:
        s = sure["error_std_mm"]
        lines += [f"The model's own std at these poses (output `error_std`, per coordinate of E − Ê): mean "
                  f"{s['mean']:.4f} mm, min {s['min']:.4f}, max {s['max']:.4f} mm; "
                  f"{100 * sure['two_sigma_coverage']:.1f} % of the residual coordinates lie within 2σ "
                  "(95 % when calibrated)."
                  + (f" {sure['above_max_std']} pose(s) above the card's bound of {sure['max_std_mm']:g} mm "
                     "(compensate warns there, P336)." if sure["max_std_mm"] is not None else ""), ""]
    for line in ident:
        lines += [line, ""]
    if data.model_card:
        lines += ["## Model card", "", "| field | value |", "|---|---|", *_card_rows(data.model_card), ""]
    lines += ["Plotted numbers: `series.csv` (per pose), `histogram.csv` (bins); figures: `summary.json`.", ""]
    path.write_text("\n".join(lines), encoding="utf-8")


def write_report(data: ReportData, folder: str | Path, title: str = "Positioning accuracy") -> dict[str, Path]:
    """Write the whole report into ``folder`` (created); returns every file by role."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise PostprocError(f"cannot create the report folder: {exc.strerror}", str(folder), code=P107) from None
    if len(data) == 0:
        raise PostprocError("no poses to report on", data.source, code=P500)
    files = write_series(data, folder)
    figures = write_plots(data, folder)
    numbers = summary(data)
    numbers["files"] = {k: p.name for k, p in {**files, **figures}.items()}
    (folder / "summary.json").write_text(json.dumps(numbers, indent=1, default=float) + "\n", encoding="utf-8")
    write_markdown(data, numbers, figures, folder / "report.md", title)
    return {**files, **figures, "summary": folder / "summary.json", "markdown": folder / "report.md"}
