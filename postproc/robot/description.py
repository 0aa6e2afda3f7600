"""A robot description (TOML) read and checked: its joints, flange, tool, payload, workspace."""
from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core import frames
from ..core.diagnostics import P330, P331, P332, P333, PostprocError
from ..core.resources import model_path
from ..core.toml import check_value, key_line, parse_toml, read_toml

__all__ = ["CONFIGURATION_FORMS", "JointSpec", "RobotDescription", "load_description", "parse_description",
           "is_description_file", "shipped_description", "robot_name", "robot_description"]


# the forms a controller states an arm configuration in ([robot] configuration; postproc.robot.configuration)
CONFIGURATION_FORMS = ("kuka", "abb", "fanuc")


# table → key → kind; "vec:n" = n numbers, "num" = a number, "str" = text, "int" = an integer
_SCHEMA: dict[str, dict[str, str]] = {
    "robot": {"name": "str", "home": "vec:6", "controller_base": "vec:6", "configuration": "str"},
    "joint": {"name": "str", "origin": "vec:6", "axis": "vec:3", "limits": "vec:2", "mass": "num",
              "com": "vec:3", "inertia": "vec:3"},
    "flange": {"origin": "vec:6"},
    "tool": {"name": "str", "frame": "vec:6"},
    "payload": {"mass": "num", "com": "vec:3", "rated": "num"},
    "workspace": {"box": "vec:6", "attitude": "vec:3", "range": "num"},
    "errors": {},  # checked by postproc.calibration.simulator, which owns the error model
    "external": {},  # [[external]]: a track / turntable (checked by postproc.robot.external)
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
    # the robot's rated payload (kg, [payload] rated): the heaviest load it is built to carry; the
    # simulator refuses heavier test loads (None: not stated, the payload's mass taken)
    payload_rated: float | None = None
    home_q: np.ndarray = field(default_factory=lambda: np.zeros(6))
    workspace: dict = field(default_factory=dict)  # box [6], attitude [3], range
    errors: dict = field(default_factory=dict)  # the raw [errors] table (see postproc.calibration.simulator)
    # the frame the robot's controller takes a program's base-relative poses in (its base), as a
    # pose X,Y,Z,A,B,C in this description's frame: 0 where the description is written in it
    # (KUKA, ABB); a UR description in ROS's base_link: 0,0,0,180,0,0 (the controller's base is
    # base_link turned 180° about Z)
    controller_base: np.ndarray = field(default_factory=lambda: np.zeros(6))
    # how the robot's controller states an arm configuration, the branch table postproc maps it
    # with (postproc.robot.configuration, docs/CONFIGURATIONS.md): "kuka" (S/T), "abb" (confdata
    # cf1, cf4, cf6, cfx), "fanuc" (CONFIG 'F U T, t1, t4, t6'); "" = the description does not
    # say (KUKA S/T is still read, as postproc's mapping on any arm; confdata and CONFIG are not)
    configuration: str = ""
    # the raw [[external]] tables: a track or a turntable beside the arm (postproc.robot.external.units_of)
    external: tuple = ()
    path: str = ""
    text: str = ""  # the file's text, to point at a key's line in messages

    def locate(self, table: str, key: str | None = None, index: int = 0) -> int:
        """1-based line of ``key`` in ``[table]`` (the ``index``-th ``[[table]]``), 0 if not found."""
        return key_line(self.text, table, key, index)

    def error(self, message: str, table: str, key: str | None = None, code: str = P332) -> PostprocError:
        """A PostprocError pointing at ``key`` of ``[table]`` in the description file."""
        return PostprocError(message, self.path, self.locate(table, key), 1 if self.path else 0, code)

    def replace(self, **changes) -> "RobotDescription":
        """A copy with some fields changed (e.g. ``payload_mass=0``)."""
        return dataclasses.replace(self, **changes)

    # The one description → chain construction: the numpy Chain (kinematics/chain.py), the torch
    # Arm (kinematics/twin.py) and the pin.Model (kinematics/reference.py) are all built from these arrays.
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


def load_description(path: str | Path | None = None) -> RobotDescription:
    """Read a robot description (default ``models/kr500.toml``); PostprocError (P33x) with
    file:line on unknown keys, missing keys or bad values."""
    path = Path(path) if path is not None else model_path("kr500.toml")
    text, doc = read_toml(path, P330, "robot description")
    return parse_description(text, str(path), doc)


def _check_tables(doc: dict, fail_at) -> None:
    """P331 for a table the schema does not know, or of the wrong kind."""
    for table, body in doc.items():
        if table not in _SCHEMA:
            known = ", ".join(f"[{t}]" for t in _SCHEMA)
            raise fail_at(table, code=P331)(f"unknown table [{table}] (known: {known})")
        if table == "joint" and not isinstance(body, list):
            raise fail_at(table, code=P331)("joints are an array of tables: write [[joint]]")
        if table == "external":  # (a table or an array of tables: postproc.robot.external checks them)
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


def parse_description(text: str, path: str = "<robot>", doc: dict | None = None) -> RobotDescription:
    """Parse the text of a robot description (see :func:`load_description`; ``doc``: its TOML, parsed)."""
    doc = parse_toml(text, path, P330) if doc is None else doc

    def fail_at(table: str, key: str | None = None, index: int = 0, code: str = P332):
        return lambda message: PostprocError(message, path, key_line(text, table, key, index) or 1, 1, code)

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
    if "rated" in payload and not payload.get("mass", 0.0) <= payload["rated"]:
        raise fail_at("payload", "rated")(f"the rated payload {payload['rated']:g} kg must be at least the payload's "
                                          f"mass {payload.get('mass', 0.0):g} kg")
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
        payload_rated=payload.get("rated"),
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
    postproc.robot.external (P227 at the key)."""
    if not raw:
        return ()
    tables = [raw] if isinstance(raw, dict) else list(raw)
    from .external import parse_external

    parse_external(tables, path)  # (malformed: refused where the description is read)
    return tuple(tables)


# --------------------------------------------------------------------------- the robot, by name or file


def is_description_file(value) -> bool:
    """Whether ``--robot VALUE`` names a description file (a .toml, or a file that exists)
    rather than a robot by its name."""
    text = str(value)
    return text.lower().endswith(".toml") or Path(text).is_file()


@functools.lru_cache(maxsize=None)
def shipped_description(name: str) -> RobotDescription | None:
    """The shipped description (``models/*.toml``) whose [robot] name or file stem is ``name``
    (any case), or None; each read once per process."""
    folder = model_path("kr500.toml").parent
    wanted = name.casefold()
    for path in sorted(folder.glob("*.toml")):
        if path.stem.casefold() == wanted:
            return load_description(path)
    for path in sorted(folder.glob("*.toml")):
        description = load_description(path)
        if description.name.casefold() == wanted:
            return description
    return None


def robot_name(value) -> str | None:
    """The name of the robot ``--robot VALUE`` means (one meaning everywhere): a description
    file's [robot] name, a shipped description's by its file stem, else VALUE itself."""
    if value is None:
        return None
    if is_description_file(value):
        return load_description(value).name
    shipped = shipped_description(str(value)) if str(value).casefold() in _shipped_stems() else None
    return shipped.name if shipped is not None else str(value)


def robot_description(value, default: str | None = "kr500.toml") -> RobotDescription:
    """The description of the robot ``--robot VALUE`` means: its file, or the shipped one of
    that name or file stem; None: ``default`` (a shipped file). P330 for a name no shipped
    description has."""
    if value is None:
        return load_description(model_path(default) if default else None)
    if is_description_file(value):
        return load_description(value)
    found = shipped_description(str(value))
    if found is None:
        raise PostprocError(f"no robot description named {value!r}: give its description file (FILE.toml), or a "
                            f"shipped robot ({', '.join(sorted(_shipped_stems()))})", str(value), 0, 0, P330)
    return found


def _shipped_stems() -> set[str]:
    return {p.stem.casefold() for p in model_path("kr500.toml").parent.glob("*.toml")}
