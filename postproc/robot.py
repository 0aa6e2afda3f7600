"""The nominal robot: a description file (TOML) → its kinematic chain, vectorised FK, gravity
torques and analytic IK; ``pin.Model`` as the reference.

A description (``models/kr500.toml`` is the example) lists the joints of a serial 6R arm with
their origins (a pure offset at q = 0 for the robots postproc ships), axes, limits and link
masses, then the flange, the tool (TCP), the payload, the workspace and optionally an
``[errors]`` table that :mod:`postproc.simulator` reads. Units at every public interface
are mm and degrees; Pinocchio works in metres and radians, converted here at the boundary.

One description → chain construction (:class:`RobotDescription`'s ``placements``, ``axes``,
``flange_matrix``, ``tool_matrix``, ``masses``, ``coms``): Pinocchio's model (built lazily with
``addJoint`` / ``appendBodyToJoint`` / ``addFrame``) is the reference FK and gravity; the
forward kinematics of many poses at once is numpy (:class:`Chain`, products of per-joint
transforms over all poses in one go), the gravity torques :func:`gravity_from_points` of its
joint frames (numpy here, torch in training/arm.py); tests/test_kinematics.py checks both,
and the torch/ONNX FK, against ``pin.framesForwardKinematics`` / ``computeGeneralizedGravity``.
The inverse kinematics is the controller's: closed form for the KUKA-type arm with a
spherical wrist (8 branches), choosing per pose the branch nearest to a reference configuration.
"""
from __future__ import annotations

import dataclasses
import math
import re
import tomllib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import frames
from .diagnostics import P330, P331, P332, P333, PostprocError, toml_error
from .resources import model_path

__all__ = ["CONFIGURATION_FORMS", "JointSpec", "RobotDescription", "load_description", "parse_description", "check_value", "Chain", "Robot",
           "axis_rotations", "GRAVITY", "gravity_torques", "gravity_from_points", "holding_torques", "pin_model"]

MM = 1e-3  # mm → m
# the forms a controller states an arm configuration in ([robot] configuration; postproc.configuration)
CONFIGURATION_FORMS = ("kuka", "abb", "fanuc")

# table → key → kind; "vec:n" = n numbers, "num" = a number, "str" = text, "int" = an integer
_SCHEMA: dict[str, dict[str, str]] = {
    "robot": {"name": "str", "home": "vec:6", "controller_base": "vec:6", "configuration": "str"},
    "joint": {"name": "str", "origin": "vec:6", "axis": "vec:3", "limits": "vec:2", "mass": "num",
              "com": "vec:3", "inertia": "vec:3"},
    "flange": {"origin": "vec:6"},
    "tool": {"name": "str", "frame": "vec:6"},
    "payload": {"mass": "num", "com": "vec:3"},
    "workspace": {"box": "vec:6", "attitude": "vec:3", "range": "num"},
    "errors": {},  # checked by postproc.simulator, which owns the error model
    "external": {},  # [[external]]: a track / turntable (checked by postproc.external)
}
_REQUIRED = {"robot": ("name", "home"), "joint": ("name", "origin", "axis", "limits"), "flange": ("origin",),
             "tool": ("frame",)}


@dataclass(frozen=True)
class JointSpec:
    """One revolute joint: its frame in the previous one at q = 0, axis, limits, link mass."""

    name: str
    origin: np.ndarray  # [6] X,Y,Z mm, A,B,C deg
    axis: np.ndarray  # [3] unit vector in the joint's own frame
    limits: np.ndarray  # [2] deg
    mass: float = 0.0  # kg, of the link this joint moves
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))  # mm, joint frame
    inertia: np.ndarray | None = None  # [3] kg·m² principal moments about the COM (None: a 0.3 m sphere)


@dataclass(frozen=True)
class RobotDescription:
    """A robot as its description file gives it (mm, degrees, kg). Build with :func:`load_description`."""

    name: str
    joints: tuple[JointSpec, ...]
    flange: np.ndarray  # [6] flange frame in the last joint's frame
    tool: np.ndarray  # [6] TCP in the flange frame ($TOOL)
    tool_name: str = "tool"
    payload_mass: float = 0.0
    payload_com: np.ndarray = field(default_factory=lambda: np.zeros(3))  # mm, flange frame
    home_q: np.ndarray = field(default_factory=lambda: np.zeros(6))
    workspace: dict = field(default_factory=dict)  # box [6], attitude [3], range
    errors: dict = field(default_factory=dict)  # the raw [errors] table (see postproc.simulator)
    # the frame the robot's controller takes a program's base-relative poses in (its base), as a
    # pose X,Y,Z,A,B,C in this description's frame: 0 where the description is written in it
    # (KUKA, ABB); a UR description in ROS's base_link: 0,0,0,180,0,0 (the controller's base is
    # base_link turned 180° about Z)
    controller_base: np.ndarray = field(default_factory=lambda: np.zeros(6))
    # how the robot's controller states an arm configuration, the branch table postproc maps it
    # with (postproc.configuration, docs/CONFIGURATIONS.md): "kuka" (S/T), "abb" (confdata
    # cf1, cf4, cf6, cfx), "fanuc" (CONFIG 'F U T, t1, t4, t6'); "" = the description does not
    # say (KUKA S/T is still read, as postproc's mapping on any arm; confdata and CONFIG are not)
    configuration: str = ""
    # the raw [[external]] tables: a track or a turntable beside the arm (postproc.external.units_of)
    external: tuple = ()
    path: str = ""
    text: str = ""  # the file's text, to point at a key's line in messages

    def locate(self, table: str, key: str | None = None, index: int = 0) -> int:
        """1-based line of ``key`` in ``[table]`` (the ``index``-th ``[[table]]``), 0 if not found."""
        return _locate(self.text, table, key, index)

    def error(self, message: str, table: str, key: str | None = None, code: str = P332) -> PostprocError:
        """A PostprocError pointing at ``key`` of ``[table]`` in the description file."""
        return PostprocError(message, self.path, self.locate(table, key), 1 if self.path else 0, code)

    def replace(self, **changes) -> "RobotDescription":
        """A copy with some fields changed (e.g. ``payload_mass=0``)."""
        return dataclasses.replace(self, **changes)

    # The one description → chain construction: the numpy Chain, the torch Arm
    # (training/arm.py) and the pin.Model are all built from these arrays.
    @property
    def origins(self) -> np.ndarray:
        """[J, 6] each joint's frame in its parent at q = 0 (X,Y,Z mm, A,B,C deg)."""
        return np.array([j.origin for j in self.joints])

    @property
    def placements(self) -> np.ndarray:
        """[J, 4, 4] the joint origins as transforms (mm)."""
        return frames.frame_to_matrix(self.origins)

    @property
    def axes(self) -> np.ndarray:
        """[J, 3] unit joint axes, each in its joint's frame."""
        return np.array([j.axis for j in self.joints])

    @property
    def flange_matrix(self) -> np.ndarray:
        """[4, 4] the flange in the last joint's frame (mm)."""
        return frames.frame_to_matrix(self.flange)

    @property
    def tool_matrix(self) -> np.ndarray:
        """[4, 4] the TCP in the flange frame (mm)."""
        return frames.frame_to_matrix(self.tool)

    @property
    def masses(self) -> np.ndarray:
        """[J] kg of the link each joint moves."""
        return np.array([j.mass for j in self.joints], dtype=float)

    @property
    def coms(self) -> np.ndarray:
        """[J, 3] each link's centre of mass in its joint's frame (mm)."""
        return np.array([j.com for j in self.joints], dtype=float)

    @property
    def payload_com_in_last(self) -> np.ndarray:
        """[3] the payload's centre of mass in the last joint's frame (mm)."""
        return (self.flange_matrix @ np.r_[self.payload_com, 1.0])[:3]


# --------------------------------------------------------------------------- reading


def _locate(text: str, table: str, key: str | None, index: int = 0) -> int:
    current, seen = None, {}
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        head = re.match(r"^\[\[?\s*([A-Za-z0-9_.-]+)\s*\]\]?", line)
        if head:
            current = head.group(1)
            seen[current] = seen.get(current, -1) + 1
            if key is None and current == table and seen[current] == index:
                return number
            continue
        if key is not None and current == table and seen.get(table) == index:
            if re.match(rf"^{re.escape(key)}\s*=", line):
                return number
    return 0


def check_value(kind: str, value, where: str, fail) -> object:
    """``value`` as ``kind`` ("str", "int", "num" or "vec:n"), else raise ``fail(message)``."""
    if kind == "str":
        if not isinstance(value, str):
            raise fail(f"{where} must be text, got {value!r}")
        return value
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise fail(f"{where} must be an integer, got {value!r}")
        return value
    if kind == "num":
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise fail(f"{where} must be a finite number, got {value!r}")
        return float(value)
    n = int(kind.split(":")[1])
    ok = isinstance(value, list) and len(value) == n and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    if not ok:
        raise fail(f"{where} must be a list of {n} finite numbers, got {value!r}")
    return np.asarray(value, dtype=float)


def load_description(path: str | Path | None = None) -> RobotDescription:
    """Read a robot description (default ``models/kr500.toml``); PostprocError (P33x) with
    file:line on unknown keys, missing keys or bad values."""
    path = Path(path) if path is not None else model_path("kr500.toml")
    try:
        text = path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise PostprocError(f"cannot read robot description: {exc.strerror or exc}", str(path),
                            code=P330) from exc
    except UnicodeDecodeError as exc:
        raise PostprocError(f"robot description is not UTF-8 text: {exc.reason}", str(path), code=P330) from exc
    return parse_description(text, str(path))


def _toml(text: str, path: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise toml_error(exc, path, P330) from None


def _check_tables(doc: dict, fail_at) -> None:
    """P331 for a table the schema does not know, or of the wrong kind."""
    for table, body in doc.items():
        if table not in _SCHEMA:
            known = ", ".join(f"[{t}]" for t in _SCHEMA)
            raise fail_at(table, code=P331)(f"unknown table [{table}] (known: {known})")
        if table == "joint" and not isinstance(body, list):
            raise fail_at(table, code=P331)("joints are an array of tables: write [[joint]]")
        if table == "external":  # (a table or an array of tables: postproc.external checks them)
            continue
        if table != "joint" and not isinstance(body, dict):
            raise fail_at(table, code=P331)(f"[{table}] must be a table")


def _joint_spec(j: dict, fail) -> JointSpec:
    """One checked [[joint]] table → JointSpec; ``fail(key)`` makes the error at that key."""
    norm = float(np.linalg.norm(j["axis"]))
    if norm < 1e-9:
        raise fail("axis")(f"joint {j['name']}: axis must not be zero")
    if not j["limits"][0] < j["limits"][1]:
        raise fail("limits")(f"joint {j['name']}: limits must be [lower, upper] with lower < upper")
    mass = j.get("mass", 0.0)
    if mass < 0:
        raise fail("mass")(f"joint {j['name']}: mass must not be negative")
    return JointSpec(j["name"], j["origin"], j["axis"] / norm, j["limits"], mass, j.get("com", np.zeros(3)),
                     j.get("inertia"))


def parse_description(text: str, path: str = "<robot>") -> RobotDescription:
    """Parse the text of a robot description (see :func:`load_description`)."""
    doc = _toml(text, path)

    def fail_at(table: str, key: str | None = None, index: int = 0, code: str = P332):
        return lambda message: PostprocError(message, path, _locate(text, table, key, index) or 1, 1, code)

    _check_tables(doc, fail_at)

    def section(table: str, body: dict, index: int = 0) -> dict:
        out = {}
        schema = _SCHEMA[table]
        for key, value in body.items():
            if key not in schema:
                raise fail_at(table, key, index, P331)(
                    f"unknown key '{key}' in [{table}] (known: {', '.join(schema)})")
            out[key] = check_value(schema[key], value, f"[{table}] {key}", fail_at(table, key, index))
        for key in _REQUIRED.get(table, ()):
            if key not in out:
                raise fail_at(table, None, index, P331)(f"[{table}] needs '{key}'")
        return out

    for table in ("robot", "flange", "tool"):
        if table not in doc:
            raise PostprocError(f"missing table [{table}]", path, 1, 1, P331)
    robot = section("robot", doc["robot"])
    joints = []
    for i, body in enumerate(doc.get("joint", [])):
        joints.append(_joint_spec(section("joint", body, i), lambda key: fail_at("joint", key, i)))
    if len(joints) != 6:
        raise PostprocError(f"a robot needs 6 [[joint]] tables, this one has {len(joints)}", path, 1, 1, P333)
    flange = section("flange", doc["flange"])
    tool = section("tool", doc["tool"])
    payload = section("payload", doc.get("payload", {}))
    if payload.get("mass", 0.0) < 0:
        raise fail_at("payload", "mass")("payload mass must not be negative")
    workspace = section("workspace", doc.get("workspace", {}))
    home = robot["home"]
    form = robot.get("configuration", "")
    if form and form not in CONFIGURATION_FORMS:
        raise fail_at("robot", "configuration")(
            f"[robot] configuration must be one of {', '.join(CONFIGURATION_FORMS)}, not {form!r}")
    for j, (spec, q) in enumerate(zip(joints, home)):
        if not spec.limits[0] <= q <= spec.limits[1]:
            raise fail_at("robot", "home")(f"home {spec.name} = {q:g} is outside its limits {spec.limits.tolist()}")
    errors = doc.get("errors", {})
    return RobotDescription(
        name=robot["name"],
        joints=tuple(joints),
        flange=flange["origin"],
        tool=tool["frame"],
        tool_name=tool.get("name", "tool"),
        payload_mass=payload.get("mass", 0.0),
        payload_com=payload.get("com", np.zeros(3)),
        home_q=home,
        workspace=workspace,
        errors=dict(errors),
        controller_base=robot.get("controller_base", np.zeros(6)),
        configuration=form,
        external=_external_tables(doc.get("external", ()), path),
        path=path,
        text=text,
    )


def _external_tables(raw, path: str) -> tuple:
    """The [[external]] tables as given (a table or an array of tables), checked by
    postproc.external (P227 at the key)."""
    if not raw:
        return ()
    tables = [raw] if isinstance(raw, dict) else list(raw)
    from .external import parse_external

    parse_external(tables, path)  # (malformed: refused where the description is read)
    return tuple(tables)


# --------------------------------------------------------------------------- kinematics


def axis_rotations(axes: np.ndarray, q_rad: np.ndarray) -> np.ndarray:
    """Rotations about unit ``axes`` [J, 3] by angles ``q_rad`` [N, J] → [N, J, 3, 3].

    Rodrigues as c·I + s·[a]× + (1−c)·a·aᵀ: elementwise over all poses, no small matmuls."""
    axes = np.asarray(axes, float)
    k = np.zeros(axes.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -axes[..., 2], axes[..., 1], -axes[..., 0]
    k[..., 1, 0], k[..., 2, 0], k[..., 2, 1] = axes[..., 2], -axes[..., 1], axes[..., 0]
    aat = axes[..., :, None] * axes[..., None, :]
    s, c = np.sin(q_rad)[..., None, None], np.cos(q_rad)[..., None, None]
    return c * np.eye(3) + s * k + (1.0 - c) * aat


class Chain:
    """A serial chain of revolute joints, evaluated for many configurations at once (numpy).

    ``placements`` [J, 4, 4] (mm) are joint frames in their parents at q = 0, ``axes`` [J, 3]
    unit axes in the joint frames, ``end`` [4, 4] the end frame (flange, TCP) in the last joint
    frame and ``base`` [4, 4] the first joint's parent in the reference frame. A description's
    chain is :meth:`of`; the simulator perturbs its arrays. Tested against Pinocchio's FK
    (tests/test_kinematics.py).
    """

    def __init__(self, placements: np.ndarray, axes: np.ndarray, end: np.ndarray, base: np.ndarray | None = None):
        self.placements = np.asarray(placements, float)
        self.axes = np.asarray(axes, float)
        self.end = np.asarray(end, float)
        self.base = np.eye(4) if base is None else np.asarray(base, float)

    @classmethod
    def of(cls, description: RobotDescription, tool: bool = True) -> "Chain":
        """The nominal chain of a description, ending at the TCP (or at the flange)."""
        end = description.flange_matrix @ description.tool_matrix if tool else description.flange_matrix
        return cls(description.placements, description.axes, end)

    def _walk(self, q_rad: np.ndarray, count: int | None = None):
        """Each of the first ``count`` joints' rotation (after its turn) and origin, in order,
        stored component-major (rotations [3, 3, N], origins [3, N]: every step a few products
        over contiguous rows): the one FK walk, over the joints and vectorised over poses."""
        count = len(self.axes) if count is None else count
        angles = np.ascontiguousarray(q_rad[:, :count].T)  # [count, N]
        cos, sin = np.cos(angles), np.sin(angles)
        r = np.repeat(self.base[:3, :3, None], len(q_rad), axis=2)
        p = self.base[:3, 3, None]
        for j in range(count):
            m = self.placements[j]
            p = p + _times(r, m[:3, 3])
            if not np.array_equal(m[:3, :3], np.eye(3)):  # (a description's placements are pure offsets)
                r = _times(r, m[:3, :3])
            r = _turned(r, self.axes[j], cos[j], sin[j])
            yield r, p

    def joints(self, q_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint rotations [N, J, 3, 3] and origins [N, J, 3] (mm) for configurations [N, J] (radians)."""
        q_rad = np.atleast_2d(np.asarray(q_rad, float))
        rs, ps = zip(*self._walk(q_rad))
        return np.stack(rs).transpose(3, 0, 1, 2), np.stack(ps).transpose(2, 0, 1)

    def transforms(self, q_rad: np.ndarray) -> np.ndarray:
        """[N, 4, 4] end frames for configurations [N, J] (radians)."""
        q_rad = np.atleast_2d(np.asarray(q_rad, float))
        *_, (r, p) = self._walk(q_rad)
        out = np.zeros((len(q_rad), 4, 4))
        out[:, :3, :3] = _times(r, self.end[:3, :3]).transpose(2, 0, 1)
        out[:, :3, 3] = (p + _times(r, self.end[:3, 3])).T
        out[:, 3, 3] = 1.0
        return out


def _times(r: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Rotations stored component-major, r [3, 3, N], times a constant [3] → [3, N] or [3, 3] → [3, 3, N]."""
    if m.ndim == 1:
        return r[:, 0] * m[0] + r[:, 1] * m[1] + r[:, 2] * m[2]
    return np.matmul(m.T, r)


def _turned(r: np.ndarray, axis: np.ndarray, cos: np.ndarray, sin: np.ndarray) -> np.ndarray:
    """r [3, 3, N] (component-major) times the rotations about unit ``axis`` by the angles of
    ``cos``, ``sin`` [N]: about ±e_k two columns mix; any other axis by Rodrigues,
    c·r + s·r[a]× + (1 − c)·(r a) aᵀ."""
    k = int(np.argmax(np.abs(axis)))
    if abs(abs(axis[k]) - 1.0) < 1e-12:
        s = np.sign(axis[k]) * sin
        i, j = [(1, 2), (2, 0), (0, 1)][k]  # R_k mixes columns i, j: (x_i c + x_j s, x_j c − x_i s)
        out = np.empty_like(r)
        out[:, k] = r[:, k]
        out[:, i] = r[:, i] * cos + r[:, j] * s
        out[:, j] = r[:, j] * cos - r[:, i] * s
        return out
    skew = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return cos * r + sin * _times(r, skew) + (1.0 - cos) * _times(r, axis)[:, None, :] * axis[None, :, None]


# --------------------------------------------------------------------------- gravity

GRAVITY = 9.81  # m/s², along −Z of the robot base frame (Pinocchio's default)
GRAVITY_ROWS = 16_384  # poses per block of the vectorised gravity torques


def holding_torques(omega, lever):
    """τ [...] (Nm) that holds weights against gravity: τ = −ω · (l × m·g), g = (0, 0, −g), for
    joint axes ``omega`` [..., 3] in the base frame and ``lever`` [..., ≥2] (kg·m) the
    mass-weighted lever Σ m_i (c_i − p_j) the joint carries (only its x, y count). Like
    :func:`gravity_from_points` it takes numpy arrays or torch tensors alike (operators and
    indexing only): one formula for the simulator and the identification's ONNX graph."""
    return GRAVITY * (omega[..., 0] * lever[..., 1] - omega[..., 1] * lever[..., 0])


def gravity_from_points(origins, centres, omega, masses, payload_mass: float = 0.0, payload=None) -> list:
    """Joint torques (J arrays [N], Nm) that hold the arm against gravity
    (``pin.computeGeneralizedGravity``) from per-joint lists of its joint origins, links'
    centres of mass (arrays [N, 3] mm) and joint axes ``omega`` [N, 3], all in the base frame,
    and link masses [J] (kg); the payload (kg, centre ``payload`` [N, 3] mm) rides on the last
    link. τ_j = −ω_j · Σ_{i≥j} (c_i − p_j) × m_i·g, summed from the tip."""
    moment, mass, torques = 0.0, payload_mass, []  # Σ_{i≥j} m_i·c_i (x, y) and Σ_{i≥j} m_i
    if payload_mass > 0:
        moment = payload_mass * payload[:, :2]
    for j in reversed(range(len(masses))):
        moment = moment + masses[j] * centres[j][:, :2]
        mass = mass + masses[j]
        torques.append(holding_torques(omega[j], (moment - mass * origins[j][:, :2]) * MM))
    return torques[::-1]


def gravity_torques(description: RobotDescription, q_deg: np.ndarray, payload: bool = True,
                    chain: Chain | None = None) -> np.ndarray:
    """Joint torques [N, J] (Nm) that hold a description's arm (with its payload, or without)
    against gravity at joint angles [N, J] (deg): :func:`gravity_from_points` of the joint
    frames of its ``chain`` (default ``Chain.of(description, tool=False)``), all poses at once, a block of
    rows at a time (tests/test_kinematics.py checks it against ``pin.computeGeneralizedGravity``)."""
    d = description
    chain = Chain.of(d, tool=False) if chain is None else chain
    q = np.radians(np.atleast_2d(np.asarray(q_deg, float)))
    coms, axes, masses, payload_com = d.coms, d.axes, d.masses, d.payload_com_in_last
    out = np.empty_like(q)
    for start in range(0, len(q), GRAVITY_ROWS):  # blocks that stay in the cache
        rows = slice(start, start + GRAVITY_ROWS)
        origins, centres, omega = [], [], []
        for j, (r, p) in enumerate(chain._walk(q[rows])):  # ([N, 3] views of the component-major walk)
            origins.append(p.T)
            centres.append((p + _times(r, coms[j])).T)
            omega.append(_times(r, axes[j]).T)
        torques = gravity_from_points(origins, centres, omega, masses, d.payload_mass if payload else 0.0,
                                      (p + _times(r, payload_com)).T)
        out[rows] = np.stack(torques, axis=1)
    return out


def _pin_inertia(pin, mass: float, com_mm: np.ndarray, inertia: np.ndarray | None):
    moments = inertia if inertia is not None else np.full(3, 0.4 * mass * 0.3**2)
    return pin.Inertia(float(mass), np.asarray(com_mm, float) * MM, np.diag(moments))


def _se3(pin, matrix_mm: np.ndarray):
    return pin.SE3(matrix_mm[:3, :3].copy(), matrix_mm[:3, 3] * MM)


def pin_model(description: RobotDescription):
    """The reference: Pinocchio's model of a description (metres inside), built from the same
    arrays as :class:`Chain`, the payload a body of its own on the last joint at the flange,
    frames "flange" and "tcp". The numpy and torch kinematics are tested against it."""
    import pinocchio as pin

    d = description
    model = pin.Model()
    model.name = d.name
    parent = 0
    for spec, placement in zip(d.joints, d.placements):
        lo, hi = np.radians(spec.limits)
        parent = model.addJoint(
            parent, pin.JointModelRevoluteUnaligned(*spec.axis), _se3(pin, placement), spec.name,
            np.array([1e6]), np.array([10.0]), np.array([lo]), np.array([hi]))
        model.appendBodyToJoint(parent, _pin_inertia(pin, spec.mass, spec.com, spec.inertia), pin.SE3.Identity())
    flange = _se3(pin, d.flange_matrix)
    if d.payload_mass > 0:
        model.appendBodyToJoint(parent, _pin_inertia(pin, d.payload_mass, d.payload_com, None), flange)
    fid = model.addFrame(pin.Frame("flange", parent, flange, pin.FrameType.OP_FRAME))
    model.addFrame(pin.Frame("tcp", parent, fid, flange * _se3(pin, d.tool_matrix), pin.FrameType.OP_FRAME))
    return model


class Robot:
    """The nominal robot: FK (:class:`Chain`), gravity torques, the controller's IK; its
    ``pin.Model`` (``model``, ``data``: the reference, built on first use).

    >>> robot = Robot()                       # models/kr500.toml
    >>> poses = robot.fk([[0, -90, 90, 0, 45, 0]])
    >>> q, ok = robot.ik(poses)
    """

    def __init__(self, description: RobotDescription | None = None):
        self.description = description if description is not None else load_description()
        d = self.description
        self.name: str = d.name
        self.tool: np.ndarray = d.tool.copy()
        self.tool_name: str = d.tool_name
        self.home_q: np.ndarray = d.home_q.copy()
        self.joint_names: list[str] = [j.name for j in d.joints]
        self.limits: np.ndarray = np.array([j.limits for j in d.joints])  # [6, 2] deg
        self.flange_chain = Chain.of(d, tool=False)
        self.tool_matrix = d.tool_matrix
        self.chain = Chain.of(d)
        try:
            self._solver: _IkGeometry | _UrIkGeometry = _IkGeometry(self)
            self._kuka_error: PostprocError | None = None
        except PostprocError as kuka:
            try:
                self._solver = _UrIkGeometry(self)
            except PostprocError as ur:
                raise PostprocError(f"no closed-form IK for this arm: {kuka.message}; or {ur.message}",
                                    ur.path, ur.line, ur.col, ur.code) from None
            self._kuka_error = kuka
        self._model = None

    @property
    def family(self) -> str:
        """'kuka' (KUKA-type arm, spherical wrist) or 'ur' (Universal-Robots-type wrist)."""
        return self._solver.family

    @property
    def _ik(self) -> "_IkGeometry":
        """The KUKA-type geometry (training.arm.KukaIK reads its dimensions); P333 for other arms."""
        if self._kuka_error is not None:
            raise self._kuka_error
        return self._solver

    def _build_model(self) -> None:
        """The pin.Model, built once on first use (only checks need it)."""
        import pinocchio as pin

        self._model = pin_model(self.description)
        self._data = self._model.createData()
        self._pin = pin

    @property
    def model(self):
        """The ``pin.Model`` of the nominal robot with its payload (built once)."""
        if self._model is None:
            self._build_model()
        return self._model

    @property
    def data(self):
        """The ``pin.Data`` reused by every Pinocchio call."""
        if self._model is None:
            self._build_model()
        return self._data

    # ---------------------------------------------------------------- FK
    def fk_matrix(self, q_deg: np.ndarray) -> np.ndarray:
        """TCP transforms [N, 4, 4] (mm) for joint angles [N, 6] (deg)."""
        return self.chain.transforms(np.radians(np.atleast_2d(np.asarray(q_deg, float))))

    def fk(self, q_deg: np.ndarray) -> np.ndarray:
        """TCP poses X,Y,Z,A,B,C [N, 6] (mm, deg; B in [-90, 90]) for joint angles [N, 6] (deg)."""
        return frames.matrix_to_frame(self.fk_matrix(q_deg))

    def pin_fk(self, q_deg: np.ndarray, frame: str = "tcp") -> np.ndarray:
        """The reference FK, Pinocchio's (one call per pose; for checks, not for bulk work)."""
        model, data = self.model, self.data
        pin = self._pin
        fid = model.getFrameId(frame)
        q = np.radians(np.atleast_2d(np.asarray(q_deg, float)))
        out = np.zeros((len(q), 4, 4))
        for i, qi in enumerate(q):
            pin.framesForwardKinematics(model, data, qi)
            m = data.oMf[fid]
            out[i, :3, :3], out[i, :3, 3], out[i, 3, 3] = m.rotation, m.translation / MM, 1.0
        return out

    # ---------------------------------------------------------------- gravity
    def gravity_torques(self, q_deg: np.ndarray, payload: bool = True) -> np.ndarray:
        """Joint torques [N, 6] (Nm) that hold the arm (with its payload, or without) against
        gravity at joint angles [N, 6] (deg): :func:`gravity_torques`."""
        return gravity_torques(self.description, q_deg, payload, self.flange_chain)

    # ---------------------------------------------------------------- IK
    def ik(self, poses: np.ndarray, reference_q: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The controller's inverse kinematics: joint angles [N, 6] (deg) for TCP poses [N, 6]
        (robot base frame, mm/deg) and a mask of poses reachable within the joint limits.

        Of the 8 closed-form branches (shoulder, elbow, wrist) and the 360° turns of each
        joint, the one nearest to ``reference_q`` ([6] or [N, 6], default HOME) is chosen;
        rows that cannot be reached are NaN."""
        q_all, ok_all = self.ik_branches(poses, reference_q)
        ref = self.home_q if reference_q is None else np.asarray(reference_q, float)
        ref = np.broadcast_to(ref, q_all.shape[1:])
        cost = np.where(ok_all, ((q_all - ref) ** 2).sum(axis=-1), np.inf)
        best = np.argmin(cost, axis=0)
        n = np.arange(q_all.shape[1])
        q = q_all[best, n]
        ok = ok_all[best, n]
        q[~ok] = np.nan
        return q, ok

    def ik_branches(self, poses: np.ndarray, reference_q: np.ndarray | None = None,
                    check: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Every closed-form branch: joint angles [8, N, 6] (deg; each joint on the 360° turn
        nearest ``reference_q`` within its limits, default HOME) and a mask [8, N] of the
        branches that reach the pose within the limits (FK checked: 1e-6 mm, 1e-9 rad; with
        ``check`` False the caller checks the branches it uses with :meth:`reaches`).
        Which branch is which: :meth:`status_turn` of the angles."""
        poses = np.atleast_2d(np.asarray(poses, float))
        ref = self.home_q if reference_q is None else np.asarray(reference_q, float)
        ref = np.broadcast_to(ref, (len(poses), 6))
        t_tcp = frames.frame_to_matrix(poses)
        q_all, ok_all = self._solver.branches(t_tcp, np.radians(ref))
        q_all = np.degrees(q_all)
        q_all, in_limits = self.nearest_turn(q_all, ref)
        ok_all &= in_limits
        q_all[~ok_all] = np.nan
        flat = ok_all.ravel()
        if check and flat.any():  # a closed form is exact; the check guards the reachability masks themselves
            bad = ~self.reaches(q_all.reshape(-1, 6)[flat], t_tcp[np.nonzero(ok_all)[1]])
            if bad.any():  # (the row of each reaching branch, in flat order)
                idx = np.flatnonzero(flat)[bad]
                ok_all.ravel()[idx] = False
                q_all.reshape(-1, 6)[idx] = np.nan
        return q_all, ok_all

    def status_branch(self, poses: np.ndarray, status: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The branch of each pose [n, 6] whose Status is ``status`` [n], without the other seven:
        (joint angles [n, 6] deg, reach mask [n], sure [n]), the entry ``ik_branches(poses,
        zeros, check=False)`` gives that status (same numbers), where ``sure``: every reaching
        branch of the pose is clear of the shoulder, elbow and wrist boundaries, so each has the
        status of its index and no two share one (the rows not sure: solve all 8). None for an
        arm without this shortcut (UR-type)."""
        if self.family != "kuka":
            return None
        poses = np.atleast_2d(np.asarray(poses, float))
        ref = np.zeros((len(poses), 6))
        t_tcp = frames.frame_to_matrix(poses)
        status = np.asarray(status, int).reshape(len(poses))
        q, ok, sure = self._solver.status_branch(t_tcp, np.radians(ref), status)
        q = np.degrees(q)
        q, in_limits = self.nearest_turn(q, ref)
        ok &= in_limits
        q[~ok] = np.nan
        return q, ok, sure

    def nearest_pair(self, poses: np.ndarray, ref_deg: np.ndarray) -> tuple | None:
        """For a choice of the branch nearest ``ref_deg`` [n, 6]: the two branches (both wrists)
        of the arm branch (A1-A3) whose A1-A3 lie nearest ``ref_deg`` (on their nearest turns),
        as :meth:`ik_branches` (zeros, check=False) gives them: (joint angles [2, n, 6] deg,
        reach [2, n], their Status [2, n], the least squared A1-A3 distance of the other three
        arm branches [n] (inf where none reaches within the limits), sure [n] (:meth:`status_branch`)).
        A branch of another arm is at least that far from ``ref_deg``. None for a UR-type arm."""
        if self.family != "kuka":
            return None
        poses = np.atleast_2d(np.asarray(poses, float))
        n = len(poses)
        zeros = np.zeros((n, 6))
        ref_deg = np.broadcast_to(np.asarray(ref_deg, float), (n, 6))
        g = self._solver
        r_all, arms, sure = g.arm_table(frames.frame_to_matrix(poses))
        lo, hi = self.limits[:3, 0] - 1e-9, self.limits[:3, 1] + 1e-9
        far = np.empty((4, n))
        for k, (reach_ok, th1, th2, th3) in enumerate(arms):
            q = np.zeros((n, 6))  # A1-A3 as _wrist and ik_branches make them (each joint on its own)
            q[:, :3] = np.stack([g.s[0] * th1, g.s[1] * th2, g.s[2] * th3], axis=-1)
            q = np.degrees((q + np.pi) % (2 * np.pi) - np.pi)
            q, _ = self.nearest_turn(q, zeros)
            inside = ((q[:, :3] >= lo) & (q[:, :3] <= hi)).all(axis=1)
            cand, _ = self.nearest_turn(q, ref_deg)
            inside &= ((cand[:, :3] >= lo) & (cand[:, :3] <= hi)).all(axis=1)
            with np.errstate(invalid="ignore"):
                far[k] = np.where(reach_ok & inside, ((cand[:, :3] - ref_deg[:, :3]) ** 2).sum(axis=-1), np.inf)
        arm = np.argmin(far, axis=0)
        others = np.where(np.arange(4)[:, None] == arm, np.inf, far).min(axis=0)
        th = [np.choose(arm, [a[i] for a in arms]) for i in (1, 2, 3)]
        reach = np.choose(arm, [a[0] for a in arms])
        q_pair, ok_pair, status = np.empty((2, n, 6)), np.empty((2, n), bool), np.empty((2, n), int)
        for j, flip in enumerate((1.0, -1.0)):
            q = np.degrees(g._wrist(th[0], th[1], th[2], r_all, flip, np.radians(zeros)))
            q, in_limits = self.nearest_turn(q, zeros)
            ok = reach & in_limits
            q[~ok] = np.nan
            q_pair[j], ok_pair[j], status[j] = q, ok, g.status_of(arm, np.full(n, flip))
        return q_pair, ok_pair, status, others, sure

    def reaches(self, q_deg: np.ndarray, t_tcp: np.ndarray) -> np.ndarray:
        """The FK check of IK solutions: [M] bool, joint angles [M, 6] (deg) whose TCP is the
        transform [M, 4, 4] within 1e-6 mm and 1e-9 (rotation matrix entries)."""
        back = self.fk_matrix(q_deg)
        bad = np.linalg.norm(back[:, :3, 3] - t_tcp[:, :3, 3], axis=1) > 1e-6
        bad |= np.abs(back[:, :3, :3] - t_tcp[:, :3, :3]).max(axis=(1, 2)) > 1e-9
        return ~bad

    def nearest_turn(self, q_deg: np.ndarray, ref_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Add the multiple of 360° that brings each joint nearest to the reference within its
        limits (the nearest turn, or the next one towards the inside of the limits); and a
        mask of the rows whose joints are then all within the limits."""
        lo, hi = self.limits[:, 0], self.limits[:, 1]
        with np.errstate(invalid="ignore"):
            q = q_deg + 360.0 * np.rint((ref_deg - q_deg) / 360.0)
            q += 360.0 * (q < lo - 1e-9)
            q -= 360.0 * (q > hi + 1e-9)
            inside = (q >= lo - 1e-9) & (q <= hi + 1e-9)
        return q, inside.all(axis=-1)

    def shoulder_status(self, poses: np.ndarray) -> np.ndarray | None:
        """S bit 0 of each of :meth:`ik_branches`' branches [8, N] (int8) where the branch's
        shoulder decides it (a KUKA-type arm whose wrist centre is more than 1e-3 mm off the A1
        axis: the first 4 branches in front, the last 4 behind), −1 where :meth:`status_turn`
        must compute it; None for an arm without this shortcut (UR-type)."""
        if self.family != "kuka":
            return None
        poses = np.atleast_2d(np.asarray(poses, float))
        known = self._solver.wrist_radius(frames.frame_to_matrix(poses)) > SHOULDER_MM
        side = np.repeat(np.array([0, 1], np.int8), 4)[:, None]
        return np.where(known[None, :], side, np.int8(-1))

    def status_turn(self, q_deg: np.ndarray, behind: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """KUKA Status and Turn [N] ints of joint angles [N, 6]: S bit 0 = wrist point behind
        the A1 axis (overhead), bit 1 = A3 at or beyond the stretched-arm angle, bit 2 = A5 ≤ 0
        (A5 taken in (−180°, 180°]); T bit i = A(i+1) < 0. The wrist point is the wrist centre (A5's origin) of a KUKA-type
        arm and A6's origin of a UR-type arm (UR controllers have no S/T: this is postproc's
        mapping of their shoulder, elbow and wrist branches on KUKA's bits)."""
        q = np.atleast_2d(np.asarray(q_deg, float))
        shape = q.shape[:-1]
        q = q.reshape(-1, 6)
        g = self._solver
        if behind is None:
            back = self._wrist_in_a1(np.radians(q), g.wrist_index)[:, 0] < 0
        else:  # bit 0 given where known (shoulder_status), computed where −1
            behind = np.asarray(behind).reshape(-1)
            back = behind == 1
            todo = np.flatnonzero(behind < 0)
            if len(todo):
                back[todo] = self._wrist_in_a1(np.radians(q[todo]), g.wrist_index)[:, 0] < 0
        stretched = math.degrees(g.s[2] * g.stretched)  # A3 with the forearm in line with the upper arm
        from_stretched = (q[:, 2] - stretched + 180.0) % 360.0 - 180.0
        beyond = from_stretched >= 0 if g.s[2] > 0 else from_stretched <= 0
        flipped = (q[:, 4] + 180.0) % 360.0 - 180.0 <= 0  # (a UR wrist turns ±360°: the branch, not the turn)
        status = back.astype(int) | (beyond.astype(int) << 1) | (flipped.astype(int) << 2)
        turn = ((q < 0).astype(int) << np.arange(6)).sum(axis=1)
        return status.reshape(shape), turn.reshape(shape)

    def _wrist_in_a1(self, q_rad: np.ndarray, wrist: int) -> np.ndarray:
        """The origin of joint ``wrist`` [N, 3] in A1's turned frame (relative to A1's origin):
        the chain after A1 walked only as far as needed (status bit 0 of 10^6 branches)."""
        after_a1 = Chain(self.flange_chain.placements[1:], self.flange_chain.axes[1:], np.eye(4))
        *_, (_, origin) = after_a1._walk(q_rad[:, 1:], wrist)  # joints A2 .. the wrist point's
        return origin.T

    @property
    def reach(self) -> dict:
        """Sphere that holds every reachable TCP position: centre on the A1 axis at A2's height,
        radius_max = A1→A2 offset + upper arm + forearm + wrist centre→TCP (conservative:
        nothing reachable lies outside); radius_min 0."""
        g = self._ik
        radius = math.hypot(g.a1, 0.0) + g.l2 + g.l3 + float(np.linalg.norm(g.tcp0 - g.c0))
        centre = g.p1 + np.array([0.0, 0.0, g.d1])
        return {"center": [round(float(v), 3) for v in centre], "radius_min": 0.0, "radius_max": round(radius, 3)}

    def __repr__(self) -> str:
        return f"Robot({self.name!r}, tool={self.tool.tolist()})"


# the wrist centre this far (mm) off the A1 axis or more: S bit 0 is the IK's shoulder branch
SHOULDER_MM = 1e-3


class _IkGeometry:
    """Closed-form IK of a KUKA-type arm: A1 about ±Z, A2/A3 about ±Y, spherical wrist
    A4 (±X) · A5 (±Y) · A6 (±X); joint frames parallel to the base at q = 0."""

    def __init__(self, robot: Robot):
        d = robot.description
        o, axes = d.origins, d.axes
        want = [2, 1, 1, 0, 1, 0]  # which base axis each joint turns about
        ok = np.allclose(o[:, 3:], 0.0) and all(abs(abs(axes[j, want[j]]) - 1.0) < 1e-12 for j in range(6))
        ok = ok and np.allclose(o[1:, 1], 0.0) and np.allclose(o[4:6, 2], 0.0)
        if not ok:
            raise PostprocError(
                "the analytic IK needs a KUKA-type arm: joint origins without rotation, axes A1 ±Z, A2/A3/A5 ±Y, "
                "A4/A6 ±X, all origins after A1 in the XZ plane and A4, A5, A6 on one line (spherical wrist)",
                d.path, d.locate("joint", None, 0), 1, P333)
        self.robot = robot
        self.s = np.array([axes[j, want[j]] for j in range(6)])  # axis signs
        self.p1 = o[0, :3]
        self.a1, self.d1 = o[1, 0], o[1, 2]
        self.L2 = np.array([o[2, 0], o[2, 2]])
        self.L3 = np.array([o[3, 0] + o[4, 0], o[3, 2] + o[4, 2]])
        self.l2, self.l3 = float(np.linalg.norm(self.L2)), float(np.linalg.norm(self.L3))
        self.al2, self.al3 = math.atan2(self.L2[1], self.L2[0]), math.atan2(self.L3[1], self.L3[0])
        self.c0 = robot.flange_chain.joints(np.zeros((1, 6)))[1][0, 4]  # wrist centre = A5's origin, on the A4 and A6 axes
        self.flange0 = robot.flange_chain.transforms(np.zeros((1, 6)))[0]
        self.tcp0 = (self.flange0 @ robot.tool_matrix)[:3, 3]
        self.inv_tool = frames.inverse(robot.tool_matrix)

    family = "kuka"
    wrist_index = 4  # the wrist point of S bit 0: A5's origin (the wrist centre)

    def wrist_radius(self, t_tcp: np.ndarray) -> np.ndarray:
        """[N] distance (mm) of the wrist centre of TCP transforms [N, 4, 4] from the A1 axis."""
        t_fl = t_tcp @ self.inv_tool
        c = t_fl[:, :3, 3] - t_fl[:, :3, :3] @ self.flange0[:3, :3].T @ (self.flange0[:3, 3] - self.c0) - self.p1
        return np.hypot(c[:, 0], c[:, 1])

    @property
    def stretched(self) -> float:
        """θ3 (rad) with the forearm in line with the upper arm."""
        return self.al3 - self.al2

    def _wrist_centre(self, t_tcp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(product of the six axis rotations [N, 3, 3], wrist centre relative to A1's origin [N, 3])."""
        t_fl = t_tcp @ self.inv_tool
        r_all = t_fl[:, :3, :3] @ self.flange0[:3, :3].T  # product of the six axis rotations
        c = t_fl[:, :3, 3] - r_all @ (self.flange0[:3, 3] - self.c0)
        return r_all, c - self.p1

    def _arms(self, c: np.ndarray) -> Iterator[tuple[float, float, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """The 4 arm branches (A1-A3) of wrist centres [N, 3], in ``branches``' order: (shoulder,
        elbow, reach mask, the elbow's opening γ0, θ1, θ2, θ3) [N] each (rad)."""
        # A1: the wrist centre's azimuth, in front of the A1 axis or over the top (behind)
        phi = np.arctan2(c[:, 1], c[:, 0])
        r_xy = np.hypot(c[:, 0], c[:, 1])
        for shoulder in (1.0, -1.0):
            th1 = phi if shoulder > 0 else phi + np.pi
            u = shoulder * r_xy - self.a1
            w = c[:, 2] - self.d1
            dist2 = u * u + w * w
            kappa = (dist2 - self.l2**2 - self.l3**2) / (2 * self.l2 * self.l3)
            reach_ok = np.abs(kappa) <= 1.0 + 1e-12
            gamma0 = np.arccos(np.clip(kappa, -1.0, 1.0))
            for elbow in (1.0, -1.0):
                # angle between upper arm and forearm vectors in the arm plane
                th3 = self.al3 - self.al2 - elbow * gamma0
                ang = self.al3 - th3  # direction of the forearm vector before A2's rotation
                w2 = np.stack([self.L2[0] + self.l3 * np.cos(ang), self.L2[1] + self.l3 * np.sin(ang)], axis=-1)
                th2 = np.arctan2(w2[:, 1], w2[:, 0]) - np.arctan2(w, u)
                yield shoulder, elbow, reach_ok, gamma0, th1, th2, th3

    def _wrist(self, th1: np.ndarray, th2: np.ndarray, th3: np.ndarray, r_all: np.ndarray, flip,
               ref: np.ndarray) -> np.ndarray:
        """Principal joint angles [N, 6] (rad) of an arm branch and wrist ``flip`` (±1, or [N])."""
        s = self.s
        q123 = np.stack([s[0] * th1, s[1] * th2, s[2] * th3], axis=-1)
        rw = _rz_ry(th1, th2 + th3).swapaxes(-1, -2) @ r_all  # = Rx(α) Ry(β) Rx(γ)
        sb = flip * np.hypot(rw[:, 0, 1], rw[:, 0, 2])
        beta = np.arctan2(sb, rw[:, 0, 0])
        alpha = np.arctan2(flip * rw[:, 1, 0], -flip * rw[:, 2, 0])
        gam = np.arctan2(flip * rw[:, 0, 1], flip * rw[:, 0, 2])
        singular = np.abs(sb) < 1e-10  # A5 ≈ 0: only A4 + A6 is defined; keep A4 at the reference
        if singular.any():
            alpha = np.where(singular, s[3] * ref[:, 3], alpha)
            gam = np.where(singular, np.arctan2(rw[:, 2, 1], rw[:, 1, 1]) - alpha, gam)
        q = np.concatenate([q123, np.stack([s[3] * alpha, s[4] * beta, s[5] * gam], axis=-1)], axis=-1)
        return (q + np.pi) % (2 * np.pi) - np.pi

    def branches(self, t_tcp: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The 8 closed-form solutions [8, N, 6] (rad, principal angles) of TCP transforms
        [N, 4, 4] and their reachability [8, N]; ``ref`` [N, 6] (rad) keeps A4 at a wrist
        singularity (A5 = 0, where only A4 + A6 is defined)."""
        r_all, c = self._wrist_centre(t_tcp)
        branches, valid = [], []
        for _, _, reach_ok, _, th1, th2, th3 in self._arms(c):
            for flip in (1.0, -1.0):
                branches.append(self._wrist(th1, th2, th3, r_all, flip, ref))
                valid.append(reach_ok)
        return np.stack(branches), np.stack(valid)

    # clearance (rad) from the elbow's stretched/folded and the wrist's A5 = 0/180° boundaries
    # beyond which a branch's Status is that of its index (far above the float error, ~1e-15)
    _CLEAR = 1e-9

    def arm_table(self, t_tcp: np.ndarray) -> tuple[np.ndarray, list, np.ndarray]:
        """(product of the axis rotations [N, 3, 3], the 4 arm branches (reach, θ1, θ2, θ3) [N]
        each in ``branches``' order, sure [N]): every reaching arm branch clear of the elbow
        (γ0 = 0, π) and wrist (β = 0, π) boundaries and the wrist centre off the A1 axis, so
        that each of the 8 branches has the Status of its index: shoulder·4 + elbow·2 + flip, S
        bit 0 the shoulder (:meth:`Robot.shoulder_status`), bit 1 (A3 beyond stretched) the
        elbow −1, bit 2 (A5 ≤ 0) the flip whose A5 has the sign −1 (:meth:`status_of`)."""
        r_all, c = self._wrist_centre(t_tcp)
        sure = np.hypot(c[:, 0], c[:, 1]) > SHOULDER_MM  # (= wrist_radius: S bit 0 is the shoulder's)
        arms = []
        for _, _, reach_ok, gamma0, th1, th2, th3 in self._arms(c):
            th23 = th2 + th3  # the wrist's β from the first row of Rw = (Rz(θ1)·Ry(θ2+θ3))ᵀ·R
            c23 = np.cos(th23)
            col = np.stack([np.cos(th1) * c23, np.sin(th1) * c23, -np.sin(th23)], axis=-1)
            rw0 = np.einsum("nk,nkj->nj", col, r_all)
            clear = (gamma0 > self._CLEAR) & (gamma0 < np.pi - self._CLEAR) & (np.hypot(rw0[:, 1], rw0[:, 2]) > self._CLEAR)
            sure &= ~reach_ok | clear
            arms.append((reach_ok, th1, th2, th3))
        return r_all, arms, sure

    def status_of(self, arm: np.ndarray, flip: np.ndarray) -> np.ndarray:
        """The Status of arm branch ``arm`` (0..3) with wrist ``flip`` (±1) where sure (:meth:`arm_table`)."""
        return (arm >> 1) | ((arm & 1) << 1) | (((flip * self.s[4]) < 0).astype(int) << 2)

    def status_branch(self, t_tcp: np.ndarray, ref: np.ndarray, status: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The branch of Status ``status`` [N] of each transform, alone: (principal angles [N, 6]
        rad, reach [N], sure [N] as :meth:`arm_table`) as :meth:`branches` computes that branch."""
        r_all, arms, sure = self.arm_table(t_tcp)
        want = 2 * (status & 1) + ((status >> 1) & 1)  # the arm branch (shoulder, elbow)
        flip = np.where(((status >> 2) & 1) == (1 if self.s[4] > 0 else 0), -1.0, 1.0)
        th = np.zeros((3, len(status)))
        reach = np.zeros(len(status), bool)
        for k, (reach_ok, th1, th2, th3) in enumerate(arms):
            mine = want == k
            th[:, mine] = th1[mine], th2[mine], th3[mine]
            reach[mine] = reach_ok[mine]
        return self._wrist(th[0], th[1], th[2], r_all, flip, ref), reach, sure


def ur_geometry(description) -> tuple[np.ndarray, np.ndarray]:
    """The joint origins [6, 6] and axis signs [6] of a UR-type description (the one check of
    the geometry the closed-form UR IK needs, numpy here and torch in training/arm.py); P333
    for another geometry."""
    o, axes = description.origins, description.axes
    want = [2, 1, 1, 1, 2, 1]
    ok = np.allclose(o[:, 3:], 0.0) and all(abs(abs(axes[j, want[j]]) - 1.0) < 1e-12 for j in range(6))
    ok = ok and np.allclose(axes[1], axes[2]) and np.allclose(axes[1], axes[3])
    ok = ok and np.allclose(o[1, :2], 0.0) and np.allclose(o[2:4, 1:], 0.0) and np.allclose(o[4, [0, 2]], 0.0)
    ok = ok and np.allclose(o[5, :2], 0.0) and np.allclose(o[0, :2], 0.0)
    if not ok:
        raise PostprocError(
            "the UR-type IK needs joint origins without rotation, axes A1 ±Z, A2 = A3 = A4 ±Y, A5 ±Z, A6 ±Y, "
            "A2 above A1, A3 and A4 along X from it, A5 beside A4 (Y), A6 below/above A5 (Z)",
            description.path, description.locate("joint", None, 0), 1, P333)
    return o, np.array([axes[j, want[j]] for j in range(6)])


class _UrIkGeometry:
    """Closed-form IK of a Universal-Robots-type arm (as ``models/ur10.toml``; the numpy twin of
    training.arm.UrIK, all 8 branches): A1 about ±Z; A2 = A3 = A4 about ±Y; A5 about ±Z; A6
    about ±Y; A2 above A1, A3 and A4 along X from it, A5 beside A4 (Y), A6 below A5 (Z)."""

    family = "ur"
    wrist_index = 5  # the wrist point of S bit 0: A6's origin (on the A6 axis)
    stretched = 0.0  # θ3 with the forearm in line with the upper arm

    def __init__(self, robot: Robot):
        d = robot.description
        o, self.s = ur_geometry(d)
        self.z0 = float(o[0, 2] + o[1, 2])
        self.a2, self.a3 = float(o[2, 0]), float(o[3, 0])
        self.y4 = float(o[4, 1])  # A4 → A5 along the shoulder axis
        self.z5 = float(o[5, 2])  # A5 → A6 along Z
        self.inv_end = frames.inverse(robot.flange_chain.end @ robot.tool_matrix)  # A6 frame from the TCP

    def branches(self, t_tcp: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """As :meth:`_IkGeometry.branches`; at the wrist singularity (A5 = 0) A6 keeps the reference."""
        t6 = t_tcp @ self.inv_end
        r6, p6 = t6[:, :3, :3], t6[:, :3, 3]
        rho = np.hypot(p6[:, 0], p6[:, 1])
        psi = np.arctan2(p6[:, 1], p6[:, 0])
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = self.y4 / rho
        lateral_ok = np.abs(ratio) <= 1.0
        lateral = np.arcsin(np.clip(ratio, -1.0, 1.0))
        branches, valid = [], []
        for shoulder in (1.0, -1.0):
            t1 = psi - lateral if shoulder > 0 else psi - np.pi + lateral
            c1, s1 = np.cos(t1), np.sin(t1)
            # R' = Rz(−t1)·R6 = Ry(t2 + t3 + t4)·Rz(t5)·Ry(t6)
            rp = np.einsum("nij,njk->nik", _rz_ry(-t1, np.zeros_like(t1)), r6)
            cos5 = np.clip(rp[:, 1, 1], -1.0, 1.0)
            for wrist in (1.0, -1.0):
                t5 = wrist * np.arccos(cos5)
                sin5 = np.sin(t5)
                singular = np.abs(sin5) < 1e-10
                safe = np.where(singular, 1.0, sin5)
                t6a = np.arctan2(rp[:, 1, 2] / safe, rp[:, 1, 0] / safe)
                t234 = np.arctan2(rp[:, 2, 1] / safe, -rp[:, 0, 1] / safe)
                if singular.any():  # R' = Ry(t234 + t6) (t5 = 0) or Ry(t234 − t6)·Rz(π) (t5 = π)
                    t6a = np.where(singular, self.s[5] * ref[:, 5], t6a)
                    total = np.arctan2(rp[:, 0, 2], rp[:, 0, 0] * np.sign(cos5))
                    t234 = np.where(singular, total - np.sign(cos5) * t6a, t234)
                c234, s234 = np.cos(t234), np.sin(t234)
                p5 = p6 - self.z5 * np.stack([c1 * s234, s1 * s234, c234], axis=1)
                u = c1 * p5[:, 0] + s1 * p5[:, 1]
                w = self.z0 - p5[:, 2]
                kappa = (u * u + w * w - self.a2**2 - self.a3**2) / (2 * self.a2 * self.a3)
                reach_ok = lateral_ok & (np.abs(kappa) <= 1.0 + 1e-12)
                for elbow in (1.0, -1.0):
                    t3 = elbow * np.arccos(np.clip(kappa, -1.0, 1.0))
                    t2 = np.arctan2(w, u) - np.arctan2(self.a3 * np.sin(t3), self.a2 + self.a3 * np.cos(t3))
                    t4 = t234 - t2 - t3
                    branches.append(np.stack([t1, t2, t3, t4, t5, t6a], axis=1) * self.s)
                    valid.append(reach_ok)
        q_all = (np.stack(branches) + np.pi) % (2 * np.pi) - np.pi
        return q_all, np.stack(valid)


def _rz_ry(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rz(a)·Ry(b) for angle arrays [N] (radians) → [N, 3, 3]."""
    ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
    r = np.empty(a.shape + (3, 3))
    r[..., 0, 0], r[..., 0, 1], r[..., 0, 2] = ca * cb, -sa, ca * sb
    r[..., 1, 0], r[..., 1, 1], r[..., 1, 2] = sa * cb, ca, sa * sb
    r[..., 2, 0], r[..., 2, 1], r[..., 2, 2] = -sb, 0.0, cb
    return r
