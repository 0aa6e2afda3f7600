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

__all__ = ["Geometry", "identified_geometry", "nominal_urdf", "UrdfChain", "read_urdf", "calibrated_urdf",
           "calibration_yaml", "parameters_json", "NOT_GEOMETRIC", "dh_parameters", "dh_transforms", "ur_calibration"]

MM = 1000.0  # mm per m
NOT_GEOMETRIC = ("compliance", "coupling", "backlash", "ripple")
# a URDF joint is the description's joint when its frame change leaves the axis within this (rad,
# mm) — the URDF's own rounding of its numbers is far below
MATCH_RAD, MATCH_MM = 1e-6, 1e-3


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
        from ..robot.kinematics.chain import Chain

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


def _xyz_rpy(m: np.ndarray) -> tuple[str, str]:
    """URDF origin attributes (m, rad; rpy: R = Rz(y)·Ry(p)·Rx(r), KUKA's A,B,C = y,p,r) of [4, 4] mm."""
    abc = np.radians(frames.abc_from_rotation(m[:3, :3]))
    return (" ".join(f"{v / MM:.12g}" for v in m[:3, 3]), " ".join(f"{v:.15g}" for v in abc[::-1]))


def _origin(element) -> np.ndarray:
    o = element.find("origin")
    xyz = [float(v) for v in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split()]
    rpy = [float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
    return frames.frame_to_matrix(np.r_[np.asarray(xyz) * MM, np.degrees(rpy[::-1])])


def nominal_urdf(description) -> str:
    """A URDF of ``description``'s kinematic chain (no visuals): links ``base_link``, ``link_1..6``,
    ``flange``, ``tcp``; joints ``joint_1..6`` (the description's origins and axes, limits) and fixed
    ``flange_joint`` / ``tcp_joint``."""
    robot = ET.Element("robot", name=description.name)
    ET.SubElement(robot, "link", name="base_link")
    parent = "base_link"
    for j, (spec, placement) in enumerate(zip(description.joints, description.placements), 1):
        child = f"link_{j}"
        ET.SubElement(robot, "link", name=child)
        joint = ET.SubElement(robot, "joint", name=f"joint_{j}", type="revolute")
        xyz, rpy = _xyz_rpy(placement)
        ET.SubElement(joint, "origin", xyz=xyz, rpy=rpy)
        ET.SubElement(joint, "parent", link=parent)
        ET.SubElement(joint, "child", link=child)
        ET.SubElement(joint, "axis", xyz=" ".join(f"{v:.15g}" for v in spec.axis))
        lo, hi = np.radians(spec.limits)
        ET.SubElement(joint, "limit", lower=f"{lo:.9g}", upper=f"{hi:.9g}", effort="1000", velocity="2")
        parent = child
    for name, child, m in (("flange_joint", "flange", description.flange_matrix),
                           ("tcp_joint", "tcp", description.tool_matrix)):
        ET.SubElement(robot, "link", name=child)
        joint = ET.SubElement(robot, "joint", name=name, type="fixed")
        xyz, rpy = _xyz_rpy(m)
        ET.SubElement(joint, "origin", xyz=xyz, rpy=rpy)
        ET.SubElement(joint, "parent", link=parent)
        ET.SubElement(joint, "child", link=child)
        parent = child
    ET.indent(robot)
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


@dataclass
class UrdfChain:
    """A URDF's arm: the XML tree, its six movable joints from the root to the tip, the fixed
    joints between (``fixed[j]``: those before movable joint j, ``fixed[6]``: after the last, up
    to the tip)."""

    tree: ET.Element
    joints: list
    fixed: list
    path: str

    def axis(self, j: int) -> np.ndarray:
        a = self.joints[j].find("axis")
        v = np.array([float(x) for x in (a.get("xyz") if a is not None else "1 0 0").split()])
        return v / np.linalg.norm(v)

    def zero_frames(self, origins: list[np.ndarray] | None = None) -> tuple[list[np.ndarray], np.ndarray]:
        """Each movable joint's frame at q = 0 in the root link's [6][4, 4] (mm), and the tip's."""
        out, m = [], np.eye(4)
        for j in range(6):
            for f in self.fixed[j]:
                m = m @ _origin(f)
            m = m @ (origins[j] if origins is not None else _origin(self.joints[j]))
            out.append(m)
        for f in self.fixed[6]:
            m = m @ _origin(f)
        return out, m


def read_urdf(text: str, path: str = "<urdf>", tip: str | None = None) -> UrdfChain:
    """The arm of a URDF: the path of joints from the root link to ``tip`` (default: the deepest
    link with six movable joints above it); P533 for a URDF without one such chain."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        line, col = exc.position
        raise PostprocError(f"not XML: {exc}", path, line, col + 1, P533) from None
    if root.tag != "robot":
        raise PostprocError(f"not a URDF: the root element is <{root.tag}>, not <robot>", path, 1, 1, P533)
    by_child = {}
    for joint in root.findall("joint"):
        child, parent = joint.find("child"), joint.find("parent")
        if child is None or parent is None:
            raise PostprocError(f"joint {joint.get('name')!r} has no parent or child", path, 0, 0, P533)
        by_child[child.get("link")] = joint
    links = [link.get("name") for link in root.findall("link")]

    def chain_to(link: str) -> list:
        out = []
        while link in by_child:
            joint = by_child[link]
            out.append(joint)
            link = joint.find("parent").get("link")
        return out[::-1]

    def movable(chain) -> list:
        return [j for j in chain if j.get("type") in ("revolute", "continuous")]

    if tip is None:
        candidates = [(len(chain_to(link)), link) for link in links if len(movable(chain_to(link))) == 6]
        if not candidates:
            raise PostprocError("no chain of six revolute joints from the root link", path, 0, 0, P533)
        tip = max(candidates)[1]
    elif tip not in links:
        raise PostprocError(f"no link {tip!r}", path, 0, 0, P533)
    chain = chain_to(tip)
    moving = movable(chain)
    if len(moving) != 6 or any(j.get("type") not in ("revolute", "continuous", "fixed") for j in chain):
        raise PostprocError(f"the chain to {tip!r} has {len(moving)} revolute joints (and "
                            f"{sum(j.get('type') not in ('revolute', 'continuous', 'fixed') for j in chain)} of "
                            "other kinds): a six-axis arm has six", path, 0, 0, P533)
    fixed, k = [[] for _ in range(7)], 0
    for joint in chain:
        if joint.get("type") == "fixed":
            fixed[k].append(joint)
        else:
            k += 1
    return UrdfChain(root, moving, fixed, path)


def _lines_fit(a_dirs, a_points, u_dirs, u_points) -> np.ndarray:
    """B [4, 4] mapping the description's joint axis lines (directions, points [6, 3], base) onto
    the URDF's (root link): rotation from the directions (Kabsch), shift from point-on-line."""
    h = np.asarray(u_dirs).T @ np.asarray(a_dirs)
    u, _, vt = np.linalg.svd(h)
    r = u @ np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))]) @ vt
    rows, rhs = [], []
    for a_p, u_d, u_p in zip(a_points, u_dirs, u_points):
        perp = np.eye(3) - np.outer(u_d, u_d)
        rows.append(perp)
        rhs.append(perp @ (u_p - r @ a_p))
    t = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = r, t
    return out


def _mapping(chain: UrdfChain, description) -> tuple[np.ndarray, list[np.ndarray]]:
    """(B, [C_j]) with U_j(0) = B · F_j · C_j; P533 where the URDF's joint j is not the
    description's."""
    urdf_frames, _ = chain.zero_frames()
    f = []
    m = np.eye(4)
    for placement in description.placements:
        m = m @ placement
        f.append(m)
    a_dirs = [fj[:3, :3] @ a for fj, a in zip(f, description.axes)]
    u_dirs = [uj[:3, :3] @ chain.axis(j) for j, uj in enumerate(urdf_frames)]
    # B from the first three joints' lines (two axes that are not parallel fix it), so that a joint
    # further out that is not the description's is named as the first one that does not match
    b = _lines_fit(a_dirs[:3], [fj[:3, 3] for fj in f[:3]], u_dirs[:3], [uj[:3, 3] for uj in urdf_frames[:3]])
    cs = []
    for j, (fj, uj) in enumerate(zip(f, urdf_frames)):
        c = np.linalg.inv(b @ fj) @ uj
        a = description.axes[j]
        turned = c[:3, :3] @ chain.axis(j)
        off_axis = np.linalg.norm(c[:3, 3] - (c[:3, 3] @ a) * a)
        if np.linalg.norm(turned - a) > MATCH_RAD * 1e3 or off_axis > MATCH_MM * 1e3:
            name = chain.joints[j].get("name")
            raise PostprocError(f"URDF joint {name!r} is not {description.name}'s joint {description.joints[j].name} "
                                f"(its axis is {math.degrees(np.arccos(np.clip(turned @ a, -1, 1))):.3g}° and "
                                f"{off_axis:.3g} mm off the description's at q = 0: another joint zero, direction or "
                                "length)", chain.path, 0, 0, P533)
        cs.append(c)
    return b, cs


def calibrated_urdf(text: str, geometry: Geometry, path: str = "<urdf>", tip: str | None = None,
                    model_name: str = "") -> tuple[str, dict]:
    """The nominal URDF ``text`` with ``geometry``'s corrections (module text); (the calibrated
    URDF's text, {joint name: offset [4, 4] mm, the correction origin⁻¹·origin'})."""
    chain = read_urdf(text, path, tip)
    d = geometry.description
    b, cs = _mapping(chain, d)
    # the calibrated URDF's joint frames at q = 0, in the root link: B · base' · W'_j(0) · C_j
    w, new_frames = geometry.base.copy(), []
    for placement, c in zip(geometry.placements, cs):
        w = w @ placement
        new_frames.append(b @ w @ c)
    offsets, parent = {}, np.eye(4)
    for j, joint in enumerate(chain.joints):
        for f in chain.fixed[j]:
            parent = parent @ _origin(f)
        origin = np.linalg.inv(parent) @ new_frames[j]
        offsets[joint.get("name")] = np.linalg.inv(_origin(joint)) @ origin
        _set_origin(joint, origin)
        parent = new_frames[j]
    c6 = cs[5]
    tcp_in_last = np.linalg.inv(c6) @ geometry.end  # the identified TCP in the URDF's last link
    correction = np.linalg.inv(c6) @ geometry.end @ np.linalg.inv(geometry.nominal_end) @ c6
    if chain.fixed[6]:  # the flange's fixed joint carries the identified TCP correction
        first = chain.fixed[6][0]
        origin = correction @ _origin(first)
        offsets[first.get("name")] = np.linalg.inv(_origin(first)) @ origin
        _set_origin(first, origin)
    last_link = chain.joints[5].find("child").get("link")
    ET.SubElement(chain.tree, "link", name="postproc_tcp")
    joint = ET.SubElement(chain.tree, "joint", name="postproc_tcp_joint", type="fixed")
    xyz, rpy = _xyz_rpy(tcp_in_last)
    ET.SubElement(joint, "origin", xyz=xyz, rpy=rpy)
    ET.SubElement(joint, "parent", link=last_link)
    ET.SubElement(joint, "child", link="postproc_tcp")
    comment = ET.Comment(_comment(geometry, model_name))
    chain.tree.insert(0, comment)
    ET.indent(chain.tree)
    return '<?xml version="1.0"?>\n' + ET.tostring(chain.tree, encoding="unicode") + "\n", offsets


def _set_origin(joint, m: np.ndarray) -> None:
    o = joint.find("origin")
    if o is None:
        o = ET.SubElement(joint, "origin")
    o.set("xyz", _xyz_rpy(m)[0])
    o.set("rpy", _xyz_rpy(m)[1])


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
        for axis, v in zip("xyz", m[:3, 3] / MM):
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


def _chain_lines(placements, axes, end, base) -> tuple[list, np.ndarray]:
    """The joint axis lines (point, direction) at q = 0 and the end frame, in ``base``'s frame."""
    m, lines = base.copy(), []
    for placement, axis in zip(placements, axes):
        m = m @ placement
        lines.append((m[:3, 3].copy(), m[:3, :3] @ axis))
    return lines, m @ end


def dh_parameters(lines: list, end: np.ndarray, parallel: float = 1e-12) -> np.ndarray:
    """[6, 4] standard DH rows (θ offset rad, d mm, a mm, α rad) of a chain whose joint axes at
    q = 0 are ``lines`` [(point, direction)] × 6 and whose end frame (DH frame 6, its z along the
    last axis) is ``end`` [4, 4], all in the DH base frame (z_0 = the first axis). Each row i
    goes from frame i−1 to frame i on the common normal of axes i and i+1 (x_i along it, turned
    the way x_{i−1} points); parallel axes (|z_{i−1} × z_i| ≤ ``parallel``) take d = 0, the last
    row ends at ``end``'s origin with its x."""
    o, x, z = np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    targets = [(p, w / np.linalg.norm(w)) for p, w in lines[1:]] + [(end[:3, 3], end[:3, 2])]
    rows = []
    for i, (p, w) in enumerate(targets):
        last = i == len(targets) - 1
        n = np.cross(z, w)
        if np.linalg.norm(n) > parallel:
            r = p - o
            b = z @ w
            s_, t_ = (z @ r - b * (w @ r)) / (1 - b * b), (b * (z @ r) - w @ r) / (1 - b * b)
            foot, new_o = o + s_ * z, p + t_ * w
            new_x = n / np.linalg.norm(n)
            d = s_
        else:
            if last:  # the end frame's origin on its line: d along the axis, a across
                d = (p - o) @ z
                foot, new_o = o + d * z, p
            else:
                d, foot = 0.0, o
                new_o = p + ((o - p) @ w) * w
            v = new_o - foot
            if last:  # DH frame 6 is the end frame: its x (what is left across is no DH row's)
                new_x = end[:3, 0] - (end[:3, 0] @ w) * w
                new_x = new_x / np.linalg.norm(new_x)
            elif np.linalg.norm(v) > 1e-9:
                new_x = v / np.linalg.norm(v)
            else:
                new_x = x
        if new_x @ x < 0:
            new_x = -new_x
        a = (new_o - foot) @ new_x
        alpha = math.atan2(np.cross(z, w) @ new_x, z @ w)
        theta = math.atan2(np.cross(x, new_x) @ z, x @ new_x)
        rows.append((theta, d, a, alpha))
        o, x, z = new_o, new_x, w
    return np.array(rows)


def dh_transforms(dh: np.ndarray, q_rad: np.ndarray) -> np.ndarray:
    """[N, 4, 4] the DH chain's end (mm) at joint angles [N, 6] rad."""
    q_rad = np.atleast_2d(q_rad)
    out = np.repeat(np.eye(4)[None], len(q_rad), axis=0)
    for i, (theta, d, a, alpha) in enumerate(dh):
        t = theta + q_rad[:, i]
        ct, st, ca, sa = np.cos(t), np.sin(t), math.cos(alpha), math.sin(alpha)
        m = np.zeros((len(q_rad), 4, 4))
        m[:, 0, 0], m[:, 0, 1], m[:, 0, 2], m[:, 0, 3] = ct, -st * ca, st * sa, a * ct
        m[:, 1, 0], m[:, 1, 1], m[:, 1, 2], m[:, 1, 3] = st, ct * ca, -ct * sa, a * st
        m[:, 2, 1], m[:, 2, 2], m[:, 2, 3] = sa, ca, d
        m[:, 3, 3] = 1.0
        out = out @ m
    return out


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
        from ..robot.kinematics.chain import Chain

        lines, flange = _chain_lines(placements, d.axes, d.flange_matrix, base)
        dh = dh_parameters(lines, flange)
        reference = Chain(placements, d.axes, d.flange_matrix, base).transforms(q)
        return dh, float(np.linalg.norm(dh_transforms(dh, q)[:, :3, 3] - reference[:, :3, 3], axis=1).max())

    nominal, nominal_off = rows(geometry.nominal_placements, to_dh)
    if nominal_off > 1e-6:
        raise PostprocError(f"{d.name}'s nominal chain is no DH chain in its controller base ({nominal_off:.3g} mm "
                            "off): the UR calibration layout does not apply", code=P533)
    # a robot's base frame is its first axis: the identified one (z along it, through the point of it
    # nearest the nominal origin, x the nominal x across it); how far that moved is the mounting's
    p1, w1 = _chain_lines(geometry.placements[:1], d.axes[:1], np.eye(4), to_dh)[0][0]
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
