"""Calibrated robot descriptions out (``postproc export``): the identified arm of a model as others
load it — a URDF, ROS robot_calibration's offsets YAML, a JSON of the identified parameters with
their std.

The geometric part of an identified model (hybrid/kinematic: the card's ``identified``) is the
nominal chain of its robot description with every joint frame moved by its identified rigid
motion and turned by its zero offset (``placement``, ``zero``: folded into the joint's origin,
as the graph folds them), the base (``base``, the measured frame the chain stands in) and the
identified TCP (``tool`` shift fixed to the flange, ``tool_rotation``): computed by the
training code's own ``kinematic.identified_chain`` (one rule). Compliance and coupling (δq =
c·τ(q)), backlash (δq = −b·s) and gear ripple (δq = a·sin nq + b·cos nq) depend on the load,
the approach direction and the angle: no URDF joint origin can hold them; the URDF names them in
a comment, the JSON lists their values, the compensator (ONNX) applies them.

**URDF.** A nominal URDF (``--urdf``; else the description's own, ``nominal_urdf``) is mapped
onto the description: its six movable joints from the root to the tip, its base B (a rigid
transform, fitted on the first three joints' axis lines at q = 0) and per joint a constant frame change C_j
that must commute with the joint's turn (its rotation maps the URDF's axis onto the
description's, its shift runs along the axis); a URDF whose joints are not the description's
(other axes, other joint zeros or directions, other lengths) is refused (P533). The calibrated
URDF keeps every element of the nominal one and rewrites the six joint origins (the base
correction in the first, zero offsets in each) and the first fixed joint after the last (the
identified TCP correction), and adds a link ``postproc_tcp`` at the identified TCP: Pinocchio's
FK of that frame is B · (the model's geometric TCP), to 1 µm (tests/test_export.py).

**robot_calibration YAML.** The same corrections as robot_calibration's offsets file:
``<joint>_x/_y/_z`` (m) and ``<joint>_a/_b/_c`` (the rotation vector, rad) of each rewritten
joint, applied as ``origin · offset`` by its ``updateURDF`` (zero offsets inside the frame
offsets: no separate joint entries, which robot_calibration would add to the joint angles).
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from ..core import frames
from ..core.diagnostics import P317, P533, PostprocError
from ..core.frames import MM
from ..robot.kinematics.chain import Chain
from ..robot.kinematics.dh import axis_lines, dh_parameters, dh_transforms
from ..robot.urdf import mapping, origin_of, read_urdf, set_origin, xyz_rpy

__all__ = ["Geometry", "identified_geometry", "calibrated_urdf", "calibration_yaml", "parameters_json", "NOT_GEOMETRIC",
           "ur_calibration"]

NOT_GEOMETRIC = ("compliance", "coupling", "backlash", "ripple")


@dataclass
class Geometry:
    """An identified arm's geometric part: ``placements`` [6, 4, 4] (joint origins, zero offsets
    folded in), ``end`` [4, 4] (the TCP in the last joint's frame), ``base`` [4, 4], mm; with the
    nominal ones of its description."""

    description: object
    placements: np.ndarray
    end: np.ndarray
    base: np.ndarray
    nominal_placements: np.ndarray
    nominal_end: np.ndarray
    identified: dict

    def tcp(self, q_deg: np.ndarray, nominal: bool = False) -> np.ndarray:
        """[N, 4, 4] the TCP (in the base's frame) at joint angles [N, 6] deg."""
        if nominal:
            chain = Chain(self.nominal_placements, self.description.axes, self.nominal_end)
        else:
            chain = Chain(self.placements, self.description.axes, self.end, self.base)
        return chain.transforms(np.radians(np.atleast_2d(np.asarray(q_deg, float))))


def identified_geometry(model, description) -> Geometry:
    """The geometric part of ``model`` (a ``Compensator`` of a hybrid/kinematic model) relative
    to ``description`` (its robot description: the card's ``identified.nominal_sha256`` must be
    its digest, else P317)."""
    import torch

    from ..model.training.kinematic import identified_chain, nominal_digest
    from ..robot.kinematics.twin import Arm, axis_rotations

    ident = model.metadata.get("identified")
    if not isinstance(ident, dict) or not isinstance(ident.get("parameters"), dict):
        raise PostprocError("the model has no identified arm (a network-only model: nothing geometric to export); "
                            "train with --method hybrid or kinematic", str(model.path), code=P317)
    digest = ident.get("nominal_sha256")
    if digest is not None and digest != nominal_digest(description):
        raise PostprocError(f"the model was identified on another robot description than {description.name!r} "
                            "(identified.nominal_sha256 differs): give its --robot", str(model.path), code=P317)
    params = ident["parameters"]
    shapes = {"placement": (6, 6), "base": (6,), "tool": (3,), "mount": (3,), "tool_rotation": (3,), "zero": (6,)}
    p = {g: torch.zeros(shape, dtype=torch.float64) for g, shape in shapes.items()}
    for group, shape in shapes.items():
        if group in params:
            p[group] = torch.as_tensor(np.asarray(params[group], float).reshape(shape))
    arm = Arm(description)
    with torch.no_grad():
        chain = identified_chain(arm, p)
        turn = axis_rotations(arm.axes, p["zero"][None, :])[0]
        placements = chain["placements"].clone()
        placements[:, :3, :3] = placements[:, :3, :3] @ turn
    return Geometry(description, placements.numpy(), chain["end"].numpy(), chain["base"].numpy(),
                    description.placements, arm.end.numpy(), ident)


# --------------------------------------------------------------------------- URDF


def calibrated_urdf(text: str, geometry: Geometry, path: str = "<urdf>", tip: str | None = None,
                    model_name: str = "") -> tuple[str, dict]:
    """The nominal URDF ``text`` with ``geometry``'s corrections (module text); (the calibrated
    URDF's text, {joint name: offset [4, 4] mm, the correction origin⁻¹·origin'})."""
    chain = read_urdf(text, path, tip)
    d = geometry.description
    b, cs = mapping(chain, d)
    # the calibrated URDF's joint frames at q = 0, in the root link: B · base' · W'_j(0) · C_j
    identified, _ = Chain(geometry.placements, d.axes, np.eye(4), geometry.base).zero_frames()
    new_frames = [b @ w @ c for w, c in zip(identified, cs)]
    offsets, parent = {}, np.eye(4)
    for j, joint in enumerate(chain.joints):
        for f in chain.fixed[j]:
            parent = parent @ origin_of(f)
        origin = np.linalg.inv(parent) @ new_frames[j]
        offsets[joint.get("name")] = np.linalg.inv(origin_of(joint)) @ origin
        set_origin(joint, origin)
        parent = new_frames[j]
    c6 = cs[5]
    tcp_in_last = np.linalg.inv(c6) @ geometry.end  # the identified TCP in the URDF's last link
    correction = np.linalg.inv(c6) @ geometry.end @ np.linalg.inv(geometry.nominal_end) @ c6
    if chain.fixed[6]:  # the flange's fixed joint carries the identified TCP correction
        first = chain.fixed[6][0]
        origin = correction @ origin_of(first)
        offsets[first.get("name")] = np.linalg.inv(origin_of(first)) @ origin
        set_origin(first, origin)
    last_link = chain.joints[5].find("child").get("link")
    ET.SubElement(chain.tree, "link", name="postproc_tcp")
    joint = ET.SubElement(chain.tree, "joint", name="postproc_tcp_joint", type="fixed")
    xyz, rpy = xyz_rpy(tcp_in_last)
    ET.SubElement(joint, "origin", xyz=xyz, rpy=rpy)
    ET.SubElement(joint, "parent", link=last_link)
    ET.SubElement(joint, "child", link="postproc_tcp")
    comment = ET.Comment(_comment(geometry, model_name))
    chain.tree.insert(0, comment)
    ET.indent(chain.tree)
    return '<?xml version="1.0"?>\n' + ET.tostring(chain.tree, encoding="unicode") + "\n", offsets


def _comment(geometry: Geometry, model_name: str) -> str:
    ident = geometry.identified
    params = ident.get("parameters", {})
    found = [g for g in NOT_GEOMETRIC[:-1] if any(abs(v) > 0 for v in params.get(g, []))]
    ripple = ident.get("ripple") or []
    if ripple:
        found.append("gear ripple (" + ", ".join(f"A{j + 1}:{n}" for j, n in ripple) + ")")
    return (f" calibrated by postproc export from model {model_name!r} (robot {geometry.description.name}): the joint "
            "origins carry the identified joint placements and zero offsets (the base correction in the first), the "
            "flange's fixed joint the identified tool correction; link postproc_tcp is the identified TCP. Not "
            f"representable in a URDF, kept in the model (ONNX) and the export's JSON: {', '.join(found) or 'none'} "
            "(load-, direction- and angle-dependent joint errors). ")


def calibration_yaml(offsets: dict, model_name: str = "") -> str:
    """robot_calibration's offsets file of the URDF corrections (module text)."""
    lines = [f"# postproc export of model {model_name!r}: robot_calibration offsets (origin' = origin * offset; "
             "_x/_y/_z m, _a/_b/_c rotation vector rad; zero offsets inside the joints' frame offsets)"]
    for name, m in offsets.items():
        rv = frames.rotvec_from_rotation(m[:3, :3])
        for axis, v in zip("xyz", m[:3, 3] * MM):
            lines.append(f"{name}_{axis}: {v:.12g}")
        for axis, v in zip("abc", rv):
            lines.append(f"{name}_{axis}: {v:.12g}")
    return "\n".join(lines) + "\n"


def parameters_json(model, geometry: Geometry | None = None) -> dict:
    """The identified parameters with their std, named and in units (``certificate.PARAMETER_NAMES``)."""
    from ..model.identified import UNIT_SCALE, PARAMETER_NAMES

    ident = model.metadata.get("identified") or {}
    params = ident.get("parameters") or {}
    stds = ident.get("parameter_posterior_std") or ident.get("parameter_std") or {}
    rows = []
    for group, values in params.items():
        names, units = PARAMETER_NAMES.get(group, (None, [""]))
        std = stds.get(group) or [None] * len(values)
        for k, (v, s) in enumerate(zip(values, std)):
            unit = units[k % len(units)]
            scale = UNIT_SCALE.get(unit, 1.0)
            rows.append({"group": group, "name": f"{group}.{names[k]}" if names and k < len(names) else f"{group}[{k}]",
                         "value": v * scale, "std": None if s is None else s * scale, "unit": unit,
                         "geometric": group not in NOT_GEOMETRIC})
    for (j, n), (a, b) in zip(ident.get("ripple") or [], ident.get("ripple_amplitudes") or []):
        for part, v in (("sin", a), ("cos", b)):
            rows.append({"group": "ripple", "name": f"ripple.A{j + 1}.order{n}.{part}", "value": math.degrees(v),
                         "std": None, "unit": "deg", "geometric": False})
    out = {"model": str(model.name), "model_sha256": model.sha256, "robot": model.robot,
           "nominal_sha256": ident.get("nominal_sha256"), "residual_std_mm": ident.get("residual_std_mm"),
           "std": "posterior (what the data knows of each value)" if ident.get("parameter_posterior_std")
           else "spread of the estimate", "parameters": rows}
    return out


# --------------------------------------------------------------------------- UR (DH)


def ur_calibration(geometry: Geometry, model_name: str = "", samples: int = 200) -> tuple[str, dict]:
    """The UR controller's calibration layout of ``geometry`` (module text): (the text of a
    ``calibration.conf``, {"dh", "nominal_dh", "delta", "residual_mm"}); P533 for an arm whose
    nominal chain is not a DH chain in its controller base (a KUKA-type description)."""
    d = geometry.description
    controller = (frames.frame_to_matrix(np.asarray(d.controller_base, float))
                  if getattr(d, "controller_base", None) is not None else np.eye(4))
    to_dh = np.linalg.inv(controller)
    rng = np.random.default_rng(0)
    q = rng.uniform(-np.pi, np.pi, (samples, 6))

    def rows(placements, base):
        chain = Chain(placements, d.axes, d.flange_matrix, base)
        dh = dh_parameters(*axis_lines(chain))
        reference = chain.transforms(q)
        return dh, float(np.linalg.norm(dh_transforms(dh, q)[:, :3, 3] - reference[:, :3, 3], axis=1).max())

    nominal, nominal_off = rows(geometry.nominal_placements, to_dh)
    if nominal_off > 1e-6:
        raise PostprocError(f"{d.name}'s nominal chain is no DH chain in its controller base ({nominal_off:.3g} mm "
                            "off): the UR calibration layout does not apply", code=P533)
    # a robot's base frame is its first axis: the identified one (z along it, through the point of it
    # nearest the nominal origin, x the nominal x across it); how far that moved is the mounting's
    p1, w1 = axis_lines(Chain(geometry.placements[:1], d.axes[:1], np.eye(4), to_dh))[0][0]
    w1 = w1 / np.linalg.norm(w1)
    mounting = np.eye(4)
    x = np.array([1.0, 0.0, 0.0]) - w1[0] * w1
    mounting[:3, 0], mounting[:3, 2] = x / np.linalg.norm(x), w1
    mounting[:3, 1] = np.cross(w1, mounting[:3, 0])
    mounting[:3, 3] = p1 - (p1 @ w1) * w1
    # the joint geometry only: the identified chain with the nominal flange (the tool's shift and
    # turn are the TCP's, set as the UR's TCP)
    dh, off = rows(geometry.placements, np.linalg.inv(mounting) @ to_dh)
    delta = dh - nominal
    delta[:, 0] = (delta[:, 0] + np.pi) % (2 * np.pi) - np.pi
    delta[:, 3] = (delta[:, 3] + np.pi) % (2 * np.pi) - np.pi

    def fmt(values, scale=1.0):
        return "[" + ", ".join(f"{v * scale:.15g}" for v in values) + "]"

    text = (f"# postproc export of model {model_name!r} ({d.name}): the identified joint geometry as a UR controller's "
            "calibration (standard DH deltas, m and rad, in the controller's base)\n"
            f"# the DH chain is {off:.4g} mm from the identified joint geometry at most over {samples} joint angle sets "
            "(what DH rows cannot hold); not in it: the base (the tracker registration), the tool's shift and turn (the "
            "UR's TCP), compliance, backlash, gear ripple\n"
            f"# the base frame is the identified first axis: {_pose_text(mounting)} (X,Y,Z mm, A,B,C deg) in the "
            "nominal controller base (the mounting's, not calibration.conf's)\n"
            f"# nominal DH: theta {fmt(nominal[:, 0])}, d {fmt(nominal[:, 1], 1e-3)}, a {fmt(nominal[:, 2], 1e-3)}, "
            f"alpha {fmt(nominal[:, 3])}\n"
            "[mounting]\n"
            f"delta_theta = {fmt(delta[:, 0])}\n"
            f"delta_a = {fmt(delta[:, 2], 1e-3)}\n"
            f"delta_d = {fmt(delta[:, 1], 1e-3)}\n"
            f"delta_alpha = {fmt(delta[:, 3])}\n")
    return text, {"dh": dh, "nominal_dh": nominal, "delta": delta, "residual_mm": off, "mounting": mounting}


def _pose_text(m: np.ndarray) -> str:
    return "{" + ", ".join(f"{v:.6g}" for v in frames.matrix_to_frame(m)) + "}"
