"""A robot description as a URDF, and a URDF's arm read back (the chain of six revolute joints)."""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from ..core import frames
from ..core.diagnostics import P533, PostprocError
from ..core.frames import MM

__all__ = ['nominal_urdf', 'UrdfChain', 'read_urdf']


def _xyz_rpy(m: np.ndarray) -> tuple[str, str]:
    """URDF origin attributes (m, rad; rpy: R = Rz(y)·Ry(p)·Rx(r), KUKA's A,B,C = y,p,r) of [4, 4] mm."""
    abc = np.radians(frames.abc_from_rotation(m[:3, :3]))
    return (" ".join(f"{v * MM:.12g}" for v in m[:3, 3]), " ".join(f"{v:.15g}" for v in abc[::-1]))


def _origin(element) -> np.ndarray:
    o = element.find("origin")
    xyz = [float(v) for v in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split()]
    rpy = [float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
    return frames.frame_to_matrix(np.r_[np.asarray(xyz) / MM, np.degrees(rpy[::-1])])


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
