"""A robot description as a URDF, and a URDF's arm read back onto a description.

:func:`nominal_urdf` writes a description's kinematic chain (no visuals) as a URDF;
:func:`read_urdf` reads a URDF's arm (:class:`UrdfChain`: the six movable joints from the root
link to a tip and the fixed joints between); :func:`mapping` maps it onto a description — its
base B (fitted on the first three joints' axis lines at q = 0) and per joint a constant frame
change C_j that must commute with the joint's turn (its rotation maps the URDF's axis onto the
description's, its shift runs along the axis), P533 for a URDF whose joints are not the
description's. :func:`origin_of` / :func:`set_origin` / :func:`xyz_rpy` read and write a joint's
``<origin>`` (m, rad, rpy: R = Rz(y)·Ry(p)·Rx(r), KUKA's A,B,C = y,p,r) as a [4, 4] in mm.
The calibrated URDF of a model is :func:`postproc.calibration.export.calibrated_urdf`.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from ..core import frames
from ..core.diagnostics import P533, PostprocError
from ..core.frames import MM
from .kinematics.chain import Chain

__all__ = ["nominal_urdf", "UrdfChain", "read_urdf", "mapping", "origin_of", "set_origin", "xyz_rpy",
           "MATCH_RAD", "MATCH_MM"]

# a URDF joint is the description's joint when its frame change leaves the axis within this (rad,
# mm) — the URDF's own rounding of its numbers is far below
MATCH_RAD, MATCH_MM = 1e-6, 1e-3


def xyz_rpy(m: np.ndarray) -> tuple[str, str]:
    """URDF origin attributes (m, rad; rpy: R = Rz(y)·Ry(p)·Rx(r), KUKA's A,B,C = y,p,r) of [4, 4] mm."""
    abc = np.radians(frames.abc_from_rotation(m[:3, :3]))
    return (" ".join(f"{v * MM:.12g}" for v in m[:3, 3]), " ".join(f"{v:.15g}" for v in abc[::-1]))


def origin_of(element) -> np.ndarray:
    """[4, 4] (mm) of an element's ``<origin>`` (identity where it has none)."""
    o = element.find("origin")
    xyz = [float(v) for v in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split()]
    rpy = [float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
    return frames.frame_to_matrix(np.r_[np.asarray(xyz) / MM, np.degrees(rpy[::-1])])


def set_origin(joint, m: np.ndarray) -> None:
    """Write [4, 4] (mm) as ``joint``'s ``<origin>`` (made where it has none)."""
    o = joint.find("origin")
    if o is None:
        o = ET.SubElement(joint, "origin")
    o.set("xyz", xyz_rpy(m)[0])
    o.set("rpy", xyz_rpy(m)[1])


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
        xyz, rpy = xyz_rpy(placement)
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
        xyz, rpy = xyz_rpy(m)
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

    def as_chain(self) -> Chain:
        """The arm as a :class:`Chain` (mm): joint j's placement the fixed joints' ``<origin>``
        before it times its own, its URDF axis, the end the fixed joints after the last."""
        placements, m = [], np.eye(4)
        for j in range(6):
            for f in self.fixed[j]:
                m = m @ origin_of(f)
            placements.append(m @ origin_of(self.joints[j]))
            m = np.eye(4)
        for f in self.fixed[6]:
            m = m @ origin_of(f)
        return Chain(np.stack(placements), np.stack([self.axis(j) for j in range(6)]), m)

    def zero_frames(self) -> tuple[list[np.ndarray], np.ndarray]:
        """Each movable joint's frame at q = 0 in the root link's [6][4, 4] (mm), and the tip's."""
        joints, tip = self.as_chain().zero_frames()
        return list(joints), tip


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
    r = frames.nearest_rotation(np.asarray(u_dirs).T @ np.asarray(a_dirs))
    rows, rhs = [], []
    for a_p, u_d, u_p in zip(a_points, u_dirs, u_points):
        perp = np.eye(3) - np.outer(u_d, u_d)
        rows.append(perp)
        rhs.append(perp @ (u_p - r @ a_p))
    t = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = r, t
    return out


def mapping(chain: UrdfChain, description) -> tuple[np.ndarray, list[np.ndarray]]:
    """(B, [C_j]) with U_j(0) = B · F_j · C_j (U_j(0): the URDF's joint frames at q = 0,
    F_j(0) the description's); P533 where the URDF's joint j is not the description's."""
    urdf_frames, _ = chain.zero_frames()
    f, _ = Chain(description.placements, description.axes, np.eye(4)).zero_frames()
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
