"""postproc export: a model's identified arm as others load it (URDF, ROS robot_calibration YAML, JSON)."""
from __future__ import annotations

import json
import sys

from .settings import ROBOT_HELP, add

EXAMPLES = """examples:
  postproc export cell3.onnx --robot models/kr500.toml -o cell3.urdf               (the description's own URDF, calibrated)
  postproc export ur10.onnx --robot models/ur10.toml --urdf ur10_nominal.urdf -o ur10_calibrated.urdf
  postproc export cell3.onnx --robot models/kr500.toml --yaml offsets.yaml --json parameters.json
  postproc export ur10.onnx --robot models/ur10.toml --ur calibration.conf          (a UR controller's DH deltas)
  postproc export --nominal --robot models/kr500.toml -o kr500.urdf                  (the nominal URDF only)

The URDF carries the identified joint placements and zero offsets (joint origins), the base (in the
first joint's origin) and the tool (the flange's fixed joint, and a link postproc_tcp at the identified
TCP); compliance, backlash and gear ripple are not representable in a URDF and are named in its comment.
--yaml writes the same corrections as ROS robot_calibration's offsets (<joint>_x.._z m, _a.._c rad);
--json every identified parameter with its std (deg, mm, deg/kNm). Needs postproc[train].
"""


def add_parser(sub, common, formatter) -> None:
    p = sub.add_parser(
        "export",
        parents=[common],
        formatter_class=formatter,
        help="a model's identified arm as a calibrated URDF, ROS robot_calibration YAML, parameter JSON",
        description="Write the identified (geometric) robot of a hybrid/kinematic model for other software.",
        epilog=EXAMPLES,
    )
    p.add_argument("model", metavar="MODEL.onnx", nargs="?", help="the compensator (hybrid or kinematic)")
    add(p, "robot", helps={"robot": ROBOT_HELP + ": the one the model was identified on (default models/kr500.toml)"})
    p.add_argument("--urdf", metavar="NOMINAL.urdf", help="the nominal URDF to calibrate (default: the description's)")
    p.add_argument("--tip", metavar="LINK", help="the URDF's last link of the arm (default: the deepest after six "
                   "revolute joints)")
    p.add_argument("-o", "--output", metavar="CALIBRATED.urdf", help="the calibrated URDF to write")
    p.add_argument("--yaml", metavar="OFFSETS.yaml", help="ROS robot_calibration offsets to write")
    p.add_argument("--json", metavar="PARAMETERS.json", help="the identified parameters with their std to write")
    p.add_argument("--ur", metavar="CALIBRATION.conf", help="a UR model: the UR controller's calibration layout (DH "
                   "deltas; the part DH rows cannot hold stated in the file)")
    p.add_argument("--nominal", action="store_true", help="write the description's nominal URDF to -o (no model)")
    p.set_defaults(run=run)


def run(args) -> int:
    from pathlib import Path

    from ..core import outputs
    from ..core.diagnostics import P308, PostprocError
    from ..robot.description import robot_description

    wanted = [p for p in (args.output, args.yaml, args.json, args.ur) if p]
    if not wanted:
        raise PostprocError("nothing to write: give -o CALIBRATED.urdf, --yaml, --json and/or --ur", code=P308)
    targets = outputs.check_outputs(wanted, [args.model, args.urdf, args.robot])
    description = robot_description(args.robot)
    from ..calibration.export import (calibrated_urdf, calibration_yaml, identified_geometry, parameters_json,
                                      ur_calibration)
    from ..robot.urdf import nominal_urdf

    if args.nominal:
        if args.yaml or args.json or args.ur or not args.output:
            raise PostprocError("--nominal writes the description's URDF to -o only", code=P308)
        outputs.write([(targets[0], nominal_urdf(description))])
        return 0
    if args.model is None:
        raise PostprocError("give MODEL.onnx (or --nominal)", code=P308)
    from ..model.compensator import load_model

    model = load_model(args.model)
    geometry = identified_geometry(model, description)
    if args.urdf:
        path = args.urdf
        try:
            text = Path(path).read_text(encoding="utf-8")
        except OSError as exc:
            from ..core.diagnostics import P107

            raise PostprocError(f"cannot read: {exc.strerror}", path, code=P107) from None
    else:
        path, text = f"<{description.name} nominal URDF>", nominal_urdf(description)
    urdf, offsets = calibrated_urdf(text, geometry, path, args.tip, model.name)
    files = []
    if args.output:
        files.append((Path(args.output), urdf))
    if args.yaml:
        files.append((Path(args.yaml), calibration_yaml(offsets, model.name)))
    if args.json:
        files.append((Path(args.json), json.dumps(parameters_json(model, geometry), indent=2) + "\n"))
    if args.ur:
        conf, ur = ur_calibration(geometry, model.name)
        files.append((Path(args.ur), conf))
        if not args.quiet:
            print(f"postproc export: UR layout: the DH chain is {ur['residual_mm']:.4g} mm from the identified one at "
                  "most (the rest DH rows cannot hold)", file=sys.stderr)
    outputs.write(files)
    if not args.quiet:
        moved = max(float(abs(m[:3, 3]).max()) for m in offsets.values())
        print(f"postproc export: {model.name} on {description.name}: {len(offsets)} joint origins corrected (largest "
              f"shift {moved:.3f} mm); wrote {', '.join(str(f) for f, _ in files)}", file=sys.stderr)
    return 0
