"""Positions in metres are refused once, naming the unit (P517, postproc/core/units.py): a pose list
compensate or check reads, a measurement CSV train reads, and a fleet's robot (it trains through
train); a demonstration model says what it is (P340), once."""
import numpy as np
import pytest

from postproc.cli import main
from postproc.compensation.api import compensate_text
from postproc.core.diagnostics import PostprocError
from postproc.core.units import unit_problem

ROWS = np.array([[1850.0, -400.0, 900.0, 0.0, 90.0, 0.0], [1913.158, -273.684, 991.234, 2.0, 88.0, -1.0],
                 [2018.421, -63.158, 1090.61, -1.0, 91.0, 0.5], [2100.0, 150.0, 1000.0, 0.0, 90.0, 0.0]])


def _pose_list(rows, scale=1.0):
    return "x,y,z,a,b,c\n" + "".join(",".join(f"{v * (scale if k < 3 else 1):.6f}" for k, v in enumerate(r)) + "\n"
                                     for r in rows)


def test_the_rule():
    assert unit_problem(ROWS) is None
    said = unit_problem(ROWS / [1000, 1000, 1000, 1, 1, 1], reach_mm=3421.2)
    assert "in metres, not mm" in said and "reaches 3421 mm" in said
    # a robot too small to tell (a 4 mm reach) is not judged; errors of a robot's size are not metres
    assert unit_problem(ROWS / 1000, reach_mm=4.0) is None
    assert unit_problem(ROWS, errors=np.full((4, 3), 0.2)) is None
    assert "~1/1000 of any robot's" in unit_problem(ROWS, errors=np.full((4, 3), 5e-4))
    # measured columns in metres (errors ~1000× a robot's): named, not "another frame"
    said = unit_problem(ROWS, errors=ROWS[:, :3] * 0.999, measured=ROWS[:, :3] / 1000)
    assert "x_meas, y_meas, z_meas are in metres" in said
    assert unit_problem(ROWS, errors=np.full((4, 3), 0.2), measured=ROWS[:, :3] - 0.2) is None


def test_a_pose_list_in_metres_is_refused_naming_the_unit(tmp_path, capsys):
    path, out = tmp_path / "m.csv", tmp_path / "out.csv"
    path.write_text(_pose_list(ROWS, 1e-3))
    assert main(["compensate", str(path), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{path}:2:1: P517 every |x|, |y|, |z| is below 5" in err and "metres" in err
    assert "P309" not in err and "P302" not in err and not out.exists()
    assert main(["check", str(path)]) == 1
    found = [line for line in capsys.readouterr().out.splitlines() if " P5" in line or " P3" in line]
    assert len([f for f in found if "P517" in f]) == 1 and not [f for f in found if "P302" in f or "P309" in f]
    # the same rows in mm: compensated
    out_text, report = compensate_text(_pose_list(ROWS), None, name="mm.csv")
    assert report.compensated == len(ROWS)
    # the library refuses it too (nothing returned)
    with pytest.raises(PostprocError, match="P517"):
        compensate_text(_pose_list(ROWS, 1e-3), None, name="m.csv")


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    pytest.importorskip("scipy")
    d = tmp_path_factory.mktemp("units")
    assert main(["plan", "-n", "60", "--seed", "3", "-o", str(d / "plan.csv"), "-q"]) == 0
    assert main(["measure", str(d / "plan.csv"), "-o", str(d / "mm.csv"), "-q"]) == 0
    lines = (d / "mm.csv").read_text().splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("x,"))
    names = lines[header].split(",")
    cols = [names.index(c) for c in ("x", "y", "z", "x_meas", "y_meas", "z_meas")]
    rows = []
    for line in lines[header + 1:]:
        f = line.split(",")
        for c in cols:
            f[c] = f"{float(f[c]) / 1000:.9f}"
        rows.append(",".join(f))
    (d / "m.csv").write_text("\n".join(lines[:header + 1] + rows) + "\n")
    return d


def test_a_measurement_csv_in_metres_is_refused_by_train_and_fleet(measured, capsys):
    d = measured
    assert main(["train", str(d / "m.csv"), "-o", str(d / "m.onnx"), "--method", "kinematic"]) == 2
    err = capsys.readouterr().err
    assert f"{d / 'm.csv'}:4:1: P517" in err and "metres" in err and not (d / "m.onnx").exists()
    from postproc.fleet.jobs import RobotJob, read_inputs
    from postproc.fleet.tasks import train_robot

    job = RobotJob("metres", d / "m.csv", method="kinematic")
    result = train_robot(job, read_inputs(job))
    assert not result["ok"] and "P517" in result["error"] and "metres" in result["error"]


def test_a_model_of_simulated_data_says_it_is_a_demonstration_model(measured, capsys):
    pytest.importorskip("torch")
    d = measured
    assert main(["train", str(d / "mm.csv"), "-o", str(d / "mm.onnx"), "--method", "kinematic", "-q"]) == 0
    from postproc.model.compensator import load_model

    model = load_model(d / "mm.onnx")
    assert model.metadata["demonstration"] == {"robot": "KR500-sim", "robot_seed": 8}
    assert model.demonstration == "a demonstration model of a simulated KR500-sim"
    (d / "p.csv").write_text(_pose_list(ROWS))
    assert main(["compensate", str(d / "p.csv"), "-o", str(d / "p_out.csv"), "--model", str(d / "mm.onnx")]) == 0
    err = capsys.readouterr().err.splitlines()
    notes = [line for line in err if " P340 " in line]
    assert notes == [f"{d / 'mm.onnx'}: P340 model mm: a demonstration model of a simulated KR500-sim — train one for "
                     "your robot: postproc train MEASURED.csv --robot ROBOT.toml -o MODEL.onnx (models/README.md)"]
    assert err[-1].endswith("; a demonstration model of a simulated robot (P340)")
    # two programs checked: one note
    (d / "q.csv").write_text(_pose_list(ROWS[:2]))
    assert main(["check", str(d / "p.csv"), str(d / "q.csv"), "--model", str(d / "mm.onnx")]) in (0, 1)
    assert sum(" P340 " in line for line in capsys.readouterr().out.splitlines()) == 1
    # the shipped default is one too; a model of other data (no such key): no note
    assert load_model(None).demonstration == "a demonstration model of a simulated KR500-sim"
    from postproc.testing.models import affine_model

    plain = load_model(affine_model(d / "plain.onnx"))
    assert plain.demonstration is None
    _, report = compensate_text(_pose_list(ROWS), plain, name="p.csv")
    assert not [n for n in report.notes if n.code == "P340"]
