"""plan --for PROGRAMS: measurement poses for the joint region, arm configurations and tools the
programs use (a KRL program in the default wrist and one in the flipped wrist, S/T stated),
chosen half space-filling, half for observability; and the targets existing data does not
cover, located (P337). The accuracy this buys (a flipped-wrist program compensated as well as
the default one) is benchmarks/plan_for.py's."""
import numpy as np
import pytest

from postproc.robot import configuration, conventions
from postproc.cli import main
from postproc.model.envelope import joint_arcs, widened_arcs
from postproc.calibration.planning import latin_hypercube, plan_configurations, read_plan, read_pose_csv
from postproc.robot.arm import Robot
from postproc.robot.description import load_description

pytest.importorskip("torch")


def _krl(poses, config, tool, name):
    lines = [f"DEF {name}( )", "$BASE = {X 0, Y 0, Z 0, A 0, B 0, C 0}",
             "$TOOL = {" + ", ".join(f"{k} {v:g}" for k, v in zip("XYZABC", tool)) + "}"]
    lines += [f"PTP {{X {p[0]:.3f}, Y {p[1]:.3f}, Z {p[2]:.3f}, A {p[3]:.4f}, B {p[4]:.4f}, C {p[5]:.4f}, "
              f"S {s}, T {t}}}" for p, (s, t) in zip(poses, config)]
    return "\n".join(lines + ["END", ""])


@pytest.fixture(scope="module")
def programs(tmp_path_factory):
    """Two programs on the KR500-sim: 30 targets in the default wrist, 30 in the flipped one
    (Status bit 2), in a smaller box than the description's workspace."""
    d = tmp_path_factory.mktemp("plan_for")
    robot = Robot(load_description())
    poses = latin_hypercube(60, box=(1850, 2150, -300, 300, 750, 1050), seed=11)
    config, ok = plan_configurations(robot, poses, "home")
    poses, config = poses[ok], config[ok]
    (d / "default.src").write_text(_krl(poses[:30], config[:30], robot.tool, "default"))
    q, found = configuration.stated_joints(robot, poses[30:60], config[30:60, 0] ^ 4, np.full(30, -1))
    s, t = conventions.status_turn_of(robot, q[found])
    (d / "flipped.src").write_text(_krl(poses[30:60][found], np.c_[s, t], robot.tool, "flipped"))
    q_default, _ = configuration.stated_joints(robot, poses[:30], config[:30, 0], config[:30, 1])
    return d, robot, {2: q_default, 6: q[found]}


def test_plan_for_covers_each_configuration_of_the_programs(programs, capsys):
    d, robot, joints = programs
    assert main(["plan", "--for", str(d / "default.src"), str(d / "flipped.src"), "-n", "40", "-o",
                 str(d / "plan.csv"), "--krl", str(d / "measure.src")]) == 0
    assert "40 poses for 60 targets of 2 program(s)" in capsys.readouterr().err
    poses, _ = read_pose_csv(d / "plan.csv")
    config = read_plan(d / "plan.csv").config
    assert len(poses) == 40 and set(np.unique(config[:, 0] & 7)) == {2, 6}
    for status, q_targets in joints.items():
        rows = (config[:, 0] & 7) == status
        assert rows.sum() >= 0.2 * 40  # each configuration at least 20 % of the plan
        # each pose is reached in the configuration it states, within the targets' (widened) joint arcs
        q, found = configuration.stated_joints(robot, poses[rows], config[rows, 0], config[rows, 1])
        assert found.all()
        arcs = widened_arcs(joint_arcs(q_targets))
        inside = np.mod(q - arcs[:, 0] + 360.0, 360.0) <= (arcs[:, 1] - arcs[:, 0]) + 1e-6
        assert inside.all()
        # half space-filling, half chosen: the poses spread over the arcs, not one corner
        spread = np.ptp(q, axis=0)[:3] / (arcs[:3, 1] - arcs[:3, 0])
        assert (spread > 0.5).all()
    src = (d / "measure.src").read_text()
    assert src.count("MEASURE_HERE( )\n") == 41 and ",S 'B110'" in src  # PTP with S/T: the flipped wrist


def test_plan_for_names_the_targets_the_data_does_not_cover(programs, capsys):
    """Data measured in the default wrist only (a plan for the default program): every flipped
    target is named at its line (P337), no default target is; the new plan counts the data in
    (its information grows from the data's, not from the prior's)."""
    d, robot, _ = programs
    assert main(["plan", "--for", str(d / "default.src"), "-n", "30", "-o", str(d / "only.csv"), "-q"]) == 0
    assert main(["measure", str(d / "only.csv"), "-o", str(d / "only_m.csv"), "-q"]) == 0
    capsys.readouterr()
    assert main(["plan", "--for", str(d / "default.src"), str(d / "flipped.src"), "--data", str(d / "only_m.csv"),
                 "-n", "20", "-o", str(d / "more.csv")]) == 0
    err = capsys.readouterr().err
    located = [line for line in err.splitlines() if ": P337 " in line]
    assert located and all(line.startswith(str(d / "flipped.src") + ":") for line in located)
    assert "no rows in this arm configuration" in located[0]
    assert "30 target(s) the data does not cover (P337)" in err
    before, after = (float(v) for v in err.split("information ")[1].split(";")[0].split(" -> "))
    assert before > 1.0 and after > before
    # --data without --for, and --for with --wrist: refused before anything is written
    assert main(["plan", "--data", str(d / "only_m.csv"), "-o", str(d / "x.csv")]) == 2
    assert main(["plan", "--for", str(d / "default.src"), "--wrist", "both", "-o", str(d / "x.csv")]) == 2
    assert not (d / "x.csv").exists()


def _plan_rows(path):
    return [line for line in path.read_text().splitlines() if not line.startswith("#")]


def test_plan_for_takes_a_kuka_cell_as_compensate_does(tmp_path, capsys):
    """A normal KUKA cell (issue 38, item 3): the directory, the .src with --config, and the .src,
    its .dat and $config.dat given together are one program with the same targets, so one plan."""
    import shutil

    from helpers import REPO

    krl = REPO / "samples/krl"
    cell = tmp_path / "R1"
    (cell / "Program").mkdir(parents=True)
    (cell / "System").mkdir()
    for name in ("weld_cell.src", "weld_cell.dat"):
        shutil.copy(krl / name, cell / "Program" / name)
    shutil.copy(krl / "config" / "$config.dat", cell / "System" / "$config.dat")
    src, dat, config = cell / "Program/weld_cell.src", cell / "Program/weld_cell.dat", cell / "System/$config.dat"
    runs = {"directory": [str(cell)], "config": [str(src), "--config", str(config)],
            "files": [str(src), str(dat), str(config)]}
    plans = {}
    for name, given in runs.items():
        out = tmp_path / f"{name}.csv"
        assert main(["plan", "--for", *given, "-n", "24", "-o", str(out)]) == 0, name
        plans[name] = _plan_rows(out)
        assert "targets of 1 program(s)" in capsys.readouterr().err
    assert plans["directory"] == plans["config"] == plans["files"]
    # the module alone: its BASE_DATA and TOOL_DATA are in no file read, nothing to plan for (said)
    assert main(["plan", "--for", str(src), "-n", "24", "-o", str(tmp_path / "alone.csv")]) == 2
    assert "P512" in capsys.readouterr().err


def test_plan_for_takes_the_frames_a_program_does_not_set_as_compensate_does(tmp_path, capsys):
    """--base and --tool state the $BASE/$TOOL of a KRL program that does not set them (as
    compensate takes them): the plan's tool column is the one stated."""
    src = tmp_path / "bare.src"
    src.write_text("DEF bare()\n" + "".join(
        f"  PTP {{X {x:.1f},Y {y:.1f},Z 900.0,A 0,B 90,C 0}}\n" for x in (1900, 2000, 2100) for y in (-200, 0, 200))
        + "END\n")
    assert main(["plan", "--for", str(src), "-n", "12", "-o", str(tmp_path / "none.csv")]) == 2  # (P220: not known)
    capsys.readouterr()
    out = tmp_path / "stated.csv"
    assert main(["plan", "--for", str(src), "-n", "12", "-o", str(out), "--base", "0", "--tool", "250,0,60,0,0,0"]) == 0
    assert "# tool: 250,0,60,0,0,0" in out.read_text()
