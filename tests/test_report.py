"""postproc report: the numbers beside the plots, Table 2 and the PNGs, checked against values
computed here from the data and the affine model's formula (not from postproc's code)."""
import json
import subprocess
import sys

import numpy as np
import pytest

from postproc.cli import main
from postproc.model.compensator import load_model
from postproc.core.diagnostics import PostprocError

pytest.importorskip("matplotlib")

OFFSET = np.array([0.2, -0.1, 0.3])
GAIN = np.array([[1e-3, 0, 0], [0, -8e-4, 2e-4], [3e-4, 0, 1.2e-3]])
CENTRE = np.array([2000.0, 0.0, 900.0])


def measurement(n=120, seed=3):
    """Poses in the default envelope; E = the model's field + a part it cannot predict."""
    rng = np.random.default_rng(seed)
    poses = np.column_stack([rng.uniform([1700, -600, 500], [2300, 600, 1300], (n, 3)),
                             rng.uniform(-5, 5, n), 90 + rng.uniform(-5, 5, n), rng.uniform(-5, 5, n)])
    predicted = OFFSET + (poses[:, :3] - CENTRE) @ GAIN.T
    error = predicted + rng.normal(scale=0.05, size=(n, 3))
    return poses, error, predicted


def write_csv(path, poses, measured, after=None):
    cols = [poses, measured] + ([after] if after is not None else [])
    header = "x,y,z,a,b,c,x_meas,y_meas,z_meas" + (",x_after,y_after,z_after" if after is not None else "")
    np.savetxt(path, np.hstack(cols), fmt="%.6f", delimiter=",", header="# cell 7, 2026-11-21\n" + header, comments="")
    return path


def read_csv(path):
    with open(path) as fh:
        names = fh.readline().strip().split(",")
    table = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {name: table[:, i] for i, name in enumerate(names)}


def table2_here(d):
    return {"max": d.max(), "min": d.min(), "mean": d.mean(), "std": np.sqrt(((d - d.mean()) ** 2).sum() / (len(d) - 1))}


def png_pixels(path):
    import matplotlib.image

    head = path.read_bytes()[:8]
    assert head == b"\x89PNG\r\n\x1a\n"
    return matplotlib.image.imread(path)


def test_report_numbers_plots_and_model_card(affine, tmp_path, capsys):
    poses, error, predicted = measurement()
    # rounding to 6 decimals in the CSV is part of the data: use the file's numbers
    csv = write_csv(tmp_path / "measured.csv", poses, poses[:, :3] - error)
    table = np.loadtxt(csv, delimiter=",", skiprows=2)
    poses, error = table[:, :6], table[:, :3] - table[:, 6:9]
    predicted = OFFSET + (poses[:, :3] - CENTRE) @ GAIN.T
    after = error - predicted
    model = affine(offset=OFFSET, gain=GAIN, centre=CENTRE, name="cell7-test")
    out = tmp_path / "report"
    assert main(["report", str(csv), "--model", str(model), "-o", str(out)]) == 0
    assert "120 poses" in capsys.readouterr().err

    series = read_csv(out / "series.csv")
    assert np.allclose(np.column_stack([series[k] for k in "xyzabc"]), poses, atol=1e-6)
    assert np.allclose(np.column_stack([series[k] for k in ("ex", "ey", "ez")]), error, atol=1e-6)
    # the model runs in float32: µm agreement
    assert np.allclose(np.column_stack([series[k] for k in ("ex_pred", "ey_pred", "ez_pred")]), predicted, atol=1e-4)
    assert np.allclose(np.column_stack([series[k] for k in ("ax", "ay", "az")]), after, atol=1e-4)
    before_norm, after_norm = np.linalg.norm(error, axis=1), np.linalg.norm(after, axis=1)
    assert np.allclose(series["norm_before"], before_norm, atol=1e-6)
    assert np.allclose(series["norm_after"], after_norm, atol=1e-4)

    hist = read_csv(out / "histogram.csv")
    # 30 common bins from 0 to the largest norm, before or after
    edges = np.linspace(0, max(before_norm.max(), after_norm.max()), 31)
    assert np.allclose(np.append(hist["bin_lo"], hist["bin_hi"][-1]), edges, atol=1e-6)
    assert np.array_equal(hist["count_before"], np.histogram(before_norm, edges)[0])
    assert np.array_equal(hist["count_after"], np.histogram(after_norm, edges)[0])
    assert hist["count_before"].sum() == hist["count_after"].sum() == 120

    summary = json.loads((out / "summary.json").read_text())
    for key, norms in (("before", before_norm), ("after", after_norm)):
        for stat, value in table2_here(norms).items():
            assert summary["table2_mm"][key][stat] == pytest.approx(value, abs=1e-4), (key, stat)
    assert summary["model"]["name"] == "cell7-test" and summary["model"]["robot"] == "KR500-sim"
    assert summary["model"]["envelope"]["box"] == [1700, 2300, -600, 600, 500, 1300]
    assert summary["outside_envelope"] == 0 and summary["poses"] == 120

    md = (out / "report.md").read_text()
    b, a = table2_here(before_norm), table2_here(after_norm)
    assert f"| {b['max']:.3f} | {b['min']:.3f} | {b['mean']:.3f} | {b['std']:.3f} |" in md
    assert f"| {a['max']:.3f} | {a['min']:.3f} | {a['mean']:.3f} | {a['std']:.3f} |" in md
    assert "| name | `cell7-test` |" in md and "| robot | `KR500-sim` |" in md

    for name in ("error_histogram.png", "error_vectors.png", "predicted_vs_measured.png"):
        assert f"]({name})" in md
        assert (out / name).stat().st_size > 10_000
        pixels = png_pixels(out / name)
        assert pixels.shape[0] > 500 and pixels.shape[1] >= 1200  # readable at a glance
        assert pixels[..., :3].std() > 0.05  # not a blank canvas
    assert summary["trained_on_these_rows"] is False and "trained the model" not in md


def test_figures_say_what_on_which_data_with_units_and_a_colour_bar(affine, tmp_path):
    from postproc.acceptance.report import DPI, MIN_WIDTH_PX, make_figures, read_report_data

    poses, error, _ = measurement(n=60)
    csv = write_csv(tmp_path / "cell7.csv", poses, poses[:, :3] - error)
    model = affine(offset=OFFSET, gain=GAIN, centre=CENTRE, name="cell7-test")
    figures = make_figures(read_report_data(csv, load_model(model)))
    assert set(figures) == {"histogram", "vectors", "predicted"}
    for key, fig in figures.items():
        assert fig.get_figwidth() * DPI >= MIN_WIDTH_PX, key
        titles = [fig._suptitle.get_text() if fig._suptitle else ""] + [ax.get_title() for ax in fig.axes]
        assert any("60 poses of cell7.csv, model cell7-test" in t for t in titles), (key, titles)
        for ax in fig.axes:
            labels = [ax.get_xlabel(), ax.get_ylabel()] + ([ax.get_zlabel()] if hasattr(ax, "get_zlabel") else [])
            assert all("(mm)" in label or label.startswith("number of") for label in labels if label), (key, labels)
            assert any(labels), key
    bars = [ax for ax in figures["vectors"].axes if ax.get_ylabel().startswith("error norm |E| (mm)")]
    assert len(bars) == 1  # the arrows' colours have a scale
    assert bars[0].get_ylim() == pytest.approx((0.0, np.linalg.norm(error, axis=1).max()), abs=1e-3)


def test_a_report_on_the_models_own_training_rows_says_so(tmp_path, capsys):
    """The model card's data_sha256 is the file's: "after" is a fit, not an accuracy."""
    import hashlib

    from postproc.testing.models import affine_model

    poses, error, _ = measurement(n=40)
    csv = write_csv(tmp_path / "train.csv", poses, poses[:, :3] - error)
    sha = hashlib.sha256(csv.read_bytes()).hexdigest()
    model = affine_model(tmp_path / "m.onnx", offset=OFFSET, gain=GAIN, centre=CENTRE, data_sha256=sha)
    assert main(["report", str(csv), "--model", str(model), "-o", str(tmp_path / "r")]) == 0
    err = capsys.readouterr().err
    assert "warning: these rows trained the model" in err
    assert json.loads((tmp_path / "r" / "summary.json").read_text())["trained_on_these_rows"] is True
    assert "**these rows trained the model" in (tmp_path / "r" / "report.md").read_text()
    other = write_csv(tmp_path / "new.csv", poses[:20], poses[:20, :3] - error[:20])  # other bytes: not flagged
    assert main(["report", str(other), "--model", str(model), "-o", str(tmp_path / "r2")]) == 0
    assert "trained the model" not in capsys.readouterr().err


def test_measured_after_columns_replace_the_first_order_residual(affine, tmp_path):
    poses, error, _ = measurement(40, seed=5)
    reached_after = poses[:, :3] - np.random.default_rng(9).normal(scale=0.03, size=(40, 3))
    csv = write_csv(tmp_path / "verify.csv", poses, poses[:, :3] - error, reached_after)
    table = np.loadtxt(csv, delimiter=",", skiprows=2)
    out = tmp_path / "r"
    assert main(["report", str(csv), "--model", str(affine(offset=OFFSET)), "-o", str(out), "-q"]) == 0
    series = read_csv(out / "series.csv")
    assert np.allclose(series["norm_after"], np.linalg.norm(table[:, :3] - table[:, 9:12], axis=1), atol=1e-6)
    assert json.loads((out / "summary.json").read_text())["after"] == "measured"
    assert "measured with compensation" in (out / "report.md").read_text()


def test_poses_outside_the_envelope_are_counted(affine, tmp_path):
    poses, error, _ = measurement(30, seed=6)
    poses[:4, 0] = 1500.0  # x below the box's 1700 (− 1 mm tolerance)
    csv = write_csv(tmp_path / "m.csv", poses, poses[:, :3] - error)
    out = tmp_path / "r"
    assert main(["report", str(csv), "--model", str(affine()), "-o", str(out), "-q"]) == 0
    assert json.loads((out / "summary.json").read_text())["outside_envelope"] == 4
    assert "4 of 30 poses lie outside" in (out / "report.md").read_text()


def test_bad_input_is_located(affine, tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("x,y,z,a,b,c,x_meas,y_meas,z_meas\n1,2,3,0,90,0,1,2,nan\n")
    assert main(["report", str(bad), "--model", str(affine()), "-o", str(tmp_path / "r")]) == 2
    assert capsys.readouterr().err.startswith(f"{bad}:2:")
    from postproc.acceptance.report import read_report_data

    poses, error, _ = measurement(5)
    with pytest.raises(PostprocError, match="nothing to compare"):
        read_report_data(write_csv(tmp_path / "m.csv", poses, poses[:, :3] - error), None)


def test_matplotlib_is_imported_only_to_draw():
    code = "import sys, postproc.acceptance.report, postproc.cli.report; print('matplotlib' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.stdout.strip() == "False", done.stderr


def test_after_from_a_measurement_of_the_compensated_program(affine, tmp_path):
    poses, error, _ = measurement(50, seed=8)
    before = write_csv(tmp_path / "before.csv", poses, poses[:, :3] - error)
    rng = np.random.default_rng(4)
    commands = poses.copy()
    commands[:, :3] += error + rng.normal(scale=0.01, size=(50, 3))  # what compensate wrote
    reached = poses[:, :3] + rng.normal(scale=0.02, size=(50, 3))  # where the robot then went
    after = write_csv(tmp_path / "after.csv", commands, reached)
    reached = np.loadtxt(after, delimiter=",", skiprows=2)[:, 6:9]
    targets = np.loadtxt(before, delimiter=",", skiprows=2)[:, :3]
    out = tmp_path / "r"
    assert main(["report", str(before), "--after", str(after), "--model", str(affine()), "-o", str(out), "-q"]) == 0
    series = read_csv(out / "series.csv")
    assert np.allclose(series["norm_after"], np.linalg.norm(targets - reached, axis=1), atol=1e-6)
    assert json.loads((out / "summary.json").read_text())["after"] == "measured"
    # rows of another program (or another order) are refused, located in the after file
    write_csv(tmp_path / "shuffled.csv", commands[::-1], reached[::-1])
    with pytest.raises(PostprocError) as info:
        from postproc.acceptance.report import read_report_data

        read_report_data(before, None, tmp_path / "shuffled.csv")
    assert (info.value.code, info.value.line) == ("P503", 3) and "row 1" in info.value.message
