"""postproc fleet: simulated robots (plan + measure --robot-seed) trained as Dask tasks on a
local cluster of worker processes; one robot with bad data fails alone; reruns skip unchanged robots;
a bad fleet file is refused at its line."""
import json

import pytest

from postproc.cli import main
from postproc.core.diagnostics import PostprocError

pytest.importorskip("dask.distributed")
pytest.importorskip("pinocchio")
pytest.importorskip("torch")

from postproc.fleet.jobs import load_fleet  # noqa: E402
from postproc.fleet.table import fleet_table  # noqa: E402


@pytest.fixture(scope="module")
def cell(tmp_path_factory):
    d = tmp_path_factory.mktemp("fleet")
    assert main(["plan", "-n", "200", "--seed", "1", "-o", str(d / "plan.csv"), "-q"]) == 0
    for s in (1, 2):
        assert main(["measure", str(d / "plan.csv"), "--robot-seed", str(s), "-o", str(d / f"r{s}.csv"), "-q"]) == 0
    lines = (d / "r1.csv").read_text().splitlines()
    # bad data: a row with a non-number in x_meas (found by the header: measure writes more columns)
    header = next(i for i, line in enumerate(lines) if line.startswith("x,"))
    at = lines[header].split(",").index("x_meas")
    fields = lines[header + 4].split(",")
    fields[at] = "oops"
    bad = lines[:header + 4] + [",".join(fields)] + lines[header + 5:]
    (d / "bad.csv").write_text("\n".join(bad) + "\n")
    (d / "fleet.toml").write_text(
        '[defaults]\nmethod = "kinematic"\nargs = ["--val-fraction", "0.2"]\n\n'
        + "".join(f'[[robot]]\nname = "r{s}"\ndata = "r{s}.csv"\n\n' for s in (1, 2))
        + '[[robot]]\nname = "bad"\ndata = "bad.csv"\n')
    return d


@pytest.fixture(scope="module")
def first_run(cell):
    """(exit code, output folder) of the fleet's first run, on the local cluster the command starts
    (one robot trained at a time); its r1 model is a previous model below."""
    out = cell / "out"
    return main(["fleet", str(cell / "fleet.toml"), "-o", str(out), "--format", "csv", "--workers", "1"]), out


@pytest.fixture(scope="module")
def scheduler():
    """The address of a cluster the later runs share (its workers import their libraries once)."""
    from postproc.fleet.cluster import _local_cluster

    with _local_cluster(1) as cluster:
        yield cluster.scheduler_address


@pytest.mark.slow
def test_fleet_trains_each_robot_and_the_bad_one_fails_alone(cell, first_run, scheduler, capsys):
    code, out = first_run
    assert code == 1
    rows = {line.split(",")[0]: line.split(",") for line in (out / "fleet.csv").read_text().splitlines()[1:]}
    assert set(rows) == {"r1", "r2", "bad"}
    for s in ("r1", "r2"):
        card = json.loads((out / s / "model-card.json").read_text())
        unc, comp = float(rows[s][2]), float(rows[s][4])
        assert rows[s][1] == "200"
        assert unc == pytest.approx(card["accuracy"]["val_uncompensated_mean_mm"], abs=1e-3)
        assert comp < 0.5 * unc  # each robot's own model compensates its own error
        assert (out / s / "report" / "report.md").is_file()
        held = [ln for ln in (out / s / "held-out.csv").read_text().splitlines() if not ln.startswith("#")][1:]
        assert len(held) == card["accuracy"]["n_val"] == 40
        assert rows[s][-1] == ""
    assert "P50" in rows["bad"][-1] and rows["bad"][4] == ""
    # the robots differ (different --robot-seed): their uncompensated errors are not the same
    assert rows["r1"][2] != rows["r2"][2]
    # rerun: the good robots are skipped, the bad one is tried again; fix it and it passes
    capsys.readouterr()
    (cell / "bad.csv").write_text((cell / "r2.csv").read_text())
    assert main(["fleet", str(cell / "fleet.toml"), "-o", str(out), "--scheduler", scheduler]) == 0
    table = capsys.readouterr().out
    assert table.count("(unchanged)") == 2 and "| bad |" in table


def test_bad_fleet_file_is_refused_at_its_line(tmp_path):
    f = tmp_path / "fleet.toml"
    f.write_text('[[robot]]\nname = "a"\ndata = "a.csv"\n\n[[robot]]\nname = "b"\n')
    with pytest.raises(PostprocError) as exc:
        load_fleet(f)
    assert exc.value.code == "P610" and exc.value.line == 5 and "'data'" in str(exc.value)
    f.write_text('[[robot]]\nname = "a"\ndata = a.csv\n')
    with pytest.raises(PostprocError) as exc:
        load_fleet(f)
    assert exc.value.line == 3
    assert main(["fleet", str(f), "-o", str(tmp_path / "o")]) == 2


def test_fleet_table_formats_escape_their_cells():
    r = [{"name": "a|b", "ok": False, "error": "x.csv:3:1: P501 <bad>", "warnings": []}]
    assert "a\\|b" in fleet_table(r, "md")
    assert "&lt;bad&gt;" in fleet_table(r, "html")
    assert fleet_table(r, "csv").splitlines()[1].startswith("a|b,")


def test_moved_parameters_against_the_previous_card():
    from postproc.fleet.tasks import moved_parameters

    new = {"identified": {"offset_mm": [1.0, 2.0], "backlash_deg": 0.1, "ripple": [[1, 2]]}}
    old = {"identified": {"offset_mm": [1.0, 2.0], "backlash_deg": 0.2, "ripple": [[1, 2]]}}
    assert moved_parameters(new, old) == ["backlash_deg"]
    assert moved_parameters(new, None) == []


@pytest.mark.slow
def test_fleet_previous_model_is_updated(cell, first_run, scheduler, capsys):
    """A robot with a ``previous`` model is re-calibrated from it (train --update): its card
    says so and the fleet table lists what moved; a previous model with nothing identified
    fails that robot alone (P317)."""
    out = cell / "upd"
    old1 = first_run[1] / "r1" / "model.onnx"  # r1 identified by the fleet's first run (kinematic)
    assert main(["train", str(cell / "r1.csv"), "-o", str(cell / "dnn.onnx"), "--method", "plain", "--epochs", "5",
                 "--hidden", "4", "-q"]) == 0
    (cell / "update.toml").write_text(
        '[defaults]\nmethod = "kinematic"\nargs = ["--val-fraction", "0.2"]\n\n'
        f'[[robot]]\nname = "r1"\ndata = "r1.csv"\nprevious = "{old1.as_posix()}"\n\n'
        '[[robot]]\nname = "r2"\ndata = "r2.csv"\nprevious = "dnn.onnx"\n')
    assert main(["fleet", str(cell / "update.toml"), "-o", str(out), "--format", "csv", "--scheduler", scheduler]) == 1
    rows = {line.split(",")[0]: line for line in (out / "fleet.csv").read_text().splitlines()[1:]}
    card = json.loads((out / "r1" / "model-card.json").read_text())
    # (the data measured the orientation, which old1 fitted: the probe's turn is re-fitted too)
    assert card["update"]["rows"] == 160 and card["update"]["groups"][0] == "base"
    assert "tool_rotation" in card["update"]["groups"] and len(card["update"]["choice"]["candidates"]) == 3
    moved = [p["name"] for p in card["update"]["parameters"] if p["moved"]]
    assert moved == []  # the same robot measured again: nothing moved
    assert rows["r1"].split(",")[-1] == ""
    assert "P317" in rows["r2"]


@pytest.mark.slow
def test_local_cluster_trains_where_onnxruntime_never_is(tmp_path):
    """The local cluster: training workers (no more than robots), which never import onnxruntime
    (it slows torch's ONNX export) and run torch on one thread, and a report worker that reads
    the card and writes the report with it."""
    from dask.distributed import Client

    from postproc.fleet.cluster import REPORT, TRAIN, _local_cluster
    from postproc.fleet.jobs import RobotJob, read_inputs
    from postproc.fleet.tasks import report_robot, train_robot, write_outputs
    from postproc.model.training.synthetic import synthetic_measurements, to_csv

    def libraries(dask_worker):  # (a local function: sent by value, this module, which imports torch, is not)
        import sys

        torch = sys.modules.get("torch")
        return (*dask_worker.state.total_resources, "onnxruntime" in sys.modules,
                torch.get_num_threads() if torch else None)

    poses, measured = synthetic_measurements(80, seed=2)
    (tmp_path / "a.csv").write_text(to_csv(poses, measured))
    job = RobotJob("a", tmp_path / "a.csv", method="plain", args=["--hidden", "3", "--epochs", "5", "--val-fraction", "0.1"])
    inputs = read_inputs(job)
    with _local_cluster(4, robots=1) as cluster, Client(cluster) as client:
        trained = client.submit(train_robot, job, inputs, resources={TRAIN: 1}, pure=False)
        result = client.submit(report_robot, trained, job, inputs, resources={REPORT: 1}, pure=False).result()
        seen = sorted(client.run(libraries).values())
    result = write_outputs(result, tmp_path)
    assert result["ok"] and result["points"] == 80 and (tmp_path / "a" / "report" / "report.md").is_file()
    assert seen == [(REPORT, True, None), (TRAIN, False, 1)]
