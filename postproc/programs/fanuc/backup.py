"""A FANUC backup's own cell data: the controller's ASCII variable files (``.va``) that give what
a TP program selects or reads but does not hold — the user and tool frames (``sysframe.va``),
the position registers (``posreg.va``) and the numeric registers (``numreg.va``).

The text forms read (as the controller writes them in a backup; docs/dialects/fanuc.md):

* a variable starts with a header line ``[*SYSTEM*]$MNUFRAME  Storage: …  Access: …  : ARRAY[g,n] OF
  POSITION`` and runs to the next header; only ``$MNUFRAME``, ``$MNUTOOL`` (sysframe.va),
  ``$POSREG`` (posreg.va) and ``$NUMREG`` (numreg.va) are read, every other variable is skipped;
* a position element ``    [g,n] = 'comment'`` (sysframe.va: no comment) followed by
  ``  Group: g   Config: N U T, 0, 0, 0``, ``  X: … Y: … Z: …``, ``  W: … P: … R: …`` and, for a
  group with extended axes, ``  EXT1: … mm`` lines (a Cartesian value, mm and deg); or
  ``    [g,n] = 'comment'   Group: g`` followed by ``J1 = … deg …`` lines (a joint value); or
  ``    [g,n] = 'comment' Uninitialized``. Numbers may drop the leading zero (``.140``, ``-.000``);
  ``********`` is a component not set;
* a numeric register ``  [n] = 12  'comment'`` (an integer) or ``  [n] = -2.700000  'comment'``
  (a real), or ``[n] = Uninitialized``.

A file whose read variables do not follow these forms is refused at its line (P118); a ``.va``
of another kind is not read.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import PurePath

import numpy as np

from ...core.diagnostics import P118, P201, P203, P211, PostprocError
from ...core.frames import frame_to_matrix, matrix_to_frame, rotation_vector
from ..analysis.values import Mat, Rec, Six, Tok, Top

__all__ = ["KINDS", "VaPosition", "VaNumber", "Backup", "Served", "parse_va", "read_backup", "serve", "va_kind"]

# the .va files read, by their name (case-insensitive), and the variables read in each
KINDS = {"sysframe.va": ("$MNUFRAME", "$MNUTOOL"), "posreg.va": ("$POSREG",), "numreg.va": ("$NUMREG",)}

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|\*+"
_HEADER = re.compile(r"^\[\*[^\]]*\*\](\$?\w+)\s+Storage:.*$")
_ELEMENT = re.compile(r"^\s*\[\s*(\d+)\s*,\s*(\d+)\s*\]\s*=\s*(?:'([^'\n]*)')?\s*(.*?)\s*$")
_GROUP_ON_ELEMENT = re.compile(r"^Group:\s*(\d+)$")
_GROUP_CONFIG = re.compile(r"^\s*Group:\s*(\d+)\s+Config:\s*(.*?)\s*$")
_COMPONENT = re.compile(r"\b(X|Y|Z|W|P|R|J\d+|EXT\d+|E\d+)\s*[:=]\s*(" + _NUMBER + r")(?:\s*(mm|deg))?")
_NUMREG = re.compile(r"^\s*\[\s*(\d+)\s*\]\s*=\s*(" + _NUMBER + r"|Uninitialized)\s*(?:'[^'\n]*'\s*)?$")


def va_kind(path: str) -> str | None:
    """The kind of a .va file by its name ('sysframe.va', 'posreg.va', 'numreg.va'), None for
    another (not read)."""
    name = PurePath(path.replace("\\", "/")).name.lower()
    return name if name in KINDS else None


@dataclass(frozen=True)
class VaNumber:
    """A number of a .va file: its value (None: ``********``, not set) and its span in the text."""

    value: float | None
    start: int
    end: int


@dataclass
class VaPosition:
    """One position element ``[group, n]``: ``kind`` "cart" (``xyzwpr`` six VaNumbers, ``config``,
    ``ext`` E1… → VaNumber), "joint" (``joints`` J1… → VaNumber) or "uninit"; ``line`` its element
    line (1-based), ``comment`` as written."""

    group: int
    n: int
    kind: str
    line: int
    comment: str = ""
    xyzwpr: tuple = ()
    config: str = ""
    ext: dict = field(default_factory=dict)
    joints: dict = field(default_factory=dict)


@dataclass
class Backup:
    """The cell data of a backup's .va files: ``uframes`` / ``utools`` (n → VaPosition of motion
    group 1: $MNUFRAME[1,n], $MNUTOOL[1,n]), ``posregs`` (n → VaPosition of group 1:
    $POSREG[1,n]), ``numregs`` (n → (VaNumber | None uninitialised, line)); ``paths`` the file of
    each kind as given, ``texts`` their texts (kind → text)."""

    uframes: dict = field(default_factory=dict)
    utools: dict = field(default_factory=dict)
    posregs: dict = field(default_factory=dict)
    numregs: dict = field(default_factory=dict)
    paths: dict = field(default_factory=dict)
    texts: dict = field(default_factory=dict)


class _Lines:
    """A text's lines with their offsets, and a cursor."""

    def __init__(self, text: str):
        self.items = []
        at = 0
        for line in text.splitlines(keepends=True):
            self.items.append((line.rstrip("\r\n"), at))
            at += len(line)
        self.k = 0

    def peek(self):
        return self.items[self.k] if self.k < len(self.items) else (None, len(self.items))


def parse_va(path: str, text: str) -> dict:
    """The variables read of one .va file (its kind by ``va_kind``): variable name → elements
    (positions: (group, n) → VaPosition; $NUMREG: n → (VaNumber | None, line)). Raises
    PostprocError (P118) at the line of anything malformed in them."""
    kind = va_kind(path)
    wanted = KINDS.get(kind, ())
    lines = _Lines(text)
    out: dict = {}

    def error(k: int, col: int, message: str) -> PostprocError:
        return PostprocError(f"{PurePath(path).name}: {message}", path, k + 1, max(col, 0) + 1, P118)

    current = None
    while lines.k < len(lines.items):
        line, at = lines.items[lines.k]
        header = _HEADER.match(line)
        if header:
            current = header.group(1).upper() if header.group(1).upper() in wanted else None
            if current is not None:
                if current in out:
                    raise error(lines.k, 0, f"{current} twice")
                out[current] = {}
            lines.k += 1
            continue
        if current is None or not line.strip():
            lines.k += 1
            continue
        if current == "$NUMREG":
            m = _NUMREG.match(line)
            if m is None:
                raise error(lines.k, len(line) - len(line.lstrip()), "a $NUMREG element is '[n] = value  'comment''")
            n = int(m.group(1))
            if n in out[current]:
                raise error(lines.k, m.start(1), f"$NUMREG[{n}] twice")
            out[current][n] = (None if m.group(2) == "Uninitialized" else
                               _number(m.group(2), at + m.start(2), at + m.end(2), error, lines.k, m.start(2)),
                               lines.k + 1)
            lines.k += 1
            continue
        element = _ELEMENT.match(line)
        if element is None:
            raise error(lines.k, len(line) - len(line.lstrip()), f"expected a {current} element '[group,n] = …'")
        position = _position(current, element, lines, at, error)
        key = (position.group, position.n)
        if key in out[current]:
            raise error(position.line - 1, element.start(1), f"{current}[{key[0]},{key[1]}] twice")
        out[current][key] = position
    return out


def _number(token: str, start: int, end: int, error, k: int, col: int) -> VaNumber:
    if token.startswith("*"):
        return VaNumber(None, start, end)
    value = float(token)
    if not math.isfinite(value):
        raise error(k, col, f"'{token}' is not a finite number")
    return VaNumber(value, start, end)


def _components(line: str, at: int, error, k: int) -> dict:
    """name → (VaNumber, unit) of the components on one line (``X:  1.0   Y: …``)."""
    out = {}
    for m in _COMPONENT.finditer(line):
        name = m.group(1)
        if name in out:
            raise error(k, m.start(1), f"{name} twice on one line")
        out[name] = (_number(m.group(2), at + m.start(2), at + m.end(2), error, k, m.start(2)), m.group(3) or "")
    rest = _COMPONENT.sub("", line).strip()
    if rest:
        raise error(k, line.find(rest[:1]), f"'{rest[:20]}' is not a component 'NAME: number'")
    return out


def _position(var: str, element: re.Match, lines: _Lines, at: int, error) -> VaPosition:
    """The element that starts at the cursor's line, its value lines read (cursor after them)."""
    k0 = lines.k
    group, n = int(element.group(1)), int(element.group(2))
    comment = element.group(3) or ""
    rest = element.group(4)
    name = f"{var}[{group},{n}]"
    lines.k += 1
    if rest == "Uninitialized":
        return VaPosition(group, n, "uninit", k0 + 1, comment)
    on_element = _GROUP_ON_ELEMENT.match(rest)
    if on_element is None and rest:
        raise error(k0, element.start(4), f"{name}: '{rest[:20]}' where 'Uninitialized', 'Group: g' or nothing "
                                          "stands")
    if on_element is not None:  # a joint value: J1 = … deg lines (and EXTn: … mm), to a blank line
        if int(on_element.group(1)) != group:
            raise error(k0, element.start(4), f"{name} says Group: {on_element.group(1)}")
        joints: dict = {}
        while True:
            line, off = lines.peek()
            if line is None or not line.strip() or _ELEMENT.match(line) or _HEADER.match(line):
                break
            found = _components(line, off, error, lines.k)
            if not found or not all(c.startswith(("J", "EXT", "E")) for c in found):
                raise error(lines.k, 0, f"{name}: a joint value's line is 'J1 = … deg   J2 = … deg …'")
            joints.update({c: v for c, (v, _) in found.items()})
            lines.k += 1
        if not any(c.startswith("J") for c in joints):
            raise error(k0, element.start(4), f"{name}: a joint value without J1…")
        return VaPosition(group, n, "joint", k0 + 1, comment, joints=joints)
    line, off = lines.peek()
    gc = _GROUP_CONFIG.match(line) if line is not None else None
    if gc is None:
        raise error(min(lines.k, len(lines.items) - 1), 0, f"{name}: expected '  Group: g   Config: …' after it")
    if int(gc.group(1)) != group:
        raise error(lines.k, gc.start(1), f"{name} says Group: {gc.group(1)}")
    config = gc.group(2)
    lines.k += 1
    values: dict = {}
    for want in ("XYZ", "WPR"):
        line, off = lines.peek()
        cut = line is None or not line.strip() or _ELEMENT.match(line) or _HEADER.match(line)
        found = _components(line, off, error, lines.k) if not cut else {}
        if sorted(found) != sorted(want):
            raise error(min(lines.k, len(lines.items) - 1), 0,
                        f"{name}: expected '{'   '.join(c + ': …' for c in want)}' here")
        values.update({c: v for c, (v, _) in found.items()})
        lines.k += 1
    ext: dict = {}
    while True:  # the extended axes of the group (a track: EXT1: … mm)
        line, off = lines.peek()
        if line is None or not re.match(r"^\s*(?:EXT|E)\d+\s*[:=]", line):
            break
        for c, (v, _) in _components(line, off, error, lines.k).items():
            ext["E" + c.lstrip("EXT")] = v
        lines.k += 1
    return VaPosition(group, n, "cart", k0 + 1, comment, tuple(values[c] for c in "XYZWPR"), config, ext)


def read_backup(va: dict[str, str] | None) -> Backup | None:
    """The cell data of a backup's .va files (path → text; only sysframe.va, posreg.va and
    numreg.va are read, matched by name case-insensitively): None where none of them is given.
    Raises PostprocError (P118) on a malformed one or one kind given twice."""
    if not va:
        return None
    out = Backup()
    for path, text in va.items():
        kind = va_kind(path)
        if kind is None:
            continue
        if kind in out.paths:
            raise PostprocError(f"two {kind} given ({out.paths[kind]} and {path}): one backup at a time", path, 0, 0,
                                P118)
        out.paths[kind], out.texts[kind] = path, text
        found = parse_va(path, text)
        if kind == "sysframe.va":
            out.uframes = {n: p for (g, n), p in found.get("$MNUFRAME", {}).items() if g == 1}
            out.utools = {n: p for (g, n), p in found.get("$MNUTOOL", {}).items() if g == 1}
        elif kind == "posreg.va":
            out.posregs = {n: p for (g, n), p in found.get("$POSREG", {}).items() if g == 1}
        else:
            out.numregs = dict(found.get("$NUMREG", {}))
    return out if out.paths else None


# ----------------------------------------------------------------------------- the values served

_KEY = {"UFRAME": "uframe", "UTOOL": "utool"}  # (the frame file's tables)
# a frame of the frame file and sysframe.va's agree where they differ by no more than this (mm,
# deg): sysframe.va writes three decimals
AGREE = 0.002


@dataclass
class Served:
    """What a backup gives the analysis (``semantics.LS.undeclared``): ``values`` (name →
    value: ``UFRAME[n]`` Mat, ``UTOOL[n]`` Six, ``PR[n]`` Rec of Toks of the .va text — a target
    moved to it is left, its numbers stand in a file not rewritten —, ``R[n]`` a float),
    ``notes`` (name → the P234 text said where a program uses it), ``why`` (name → (why, code):
    the backup holds it but its value is not used), ``frames`` (sysframe.va was given),
    ``config_names`` / ``config_texts`` (the .va files, Loc.file −1, −2, …)."""

    values: dict = field(default_factory=dict)
    notes: dict = field(default_factory=dict)
    why: dict = field(default_factory=dict)
    frames: bool = False
    config_names: list = field(default_factory=list)
    config_texts: list = field(default_factory=list)


def serve(backup: Backup | None, written: dict, indirect: dict, registers: str, uframes: dict, utools: dict) -> Served:
    """The values a backup gives the programs read: ``written`` (name → where a TP program read
    sets it: "path:line"), ``indirect`` (kind "R"/"PR"/"UFRAME"/"UTOOL" → where one is set with
    an index known at run time), ``registers`` ("backup" or "runtime"), ``uframes`` / ``utools``
    the frame file's (n → 4×4 / X,Y,Z,A,B,C; a frame sysframe.va gives otherwise is taken out of
    them: the two do not agree, and which one runs is not known)."""
    out = Served()
    if backup is None:
        return out
    files = {kind: -1 - k for k, kind in enumerate(backup.paths)}
    out.config_names = list(backup.paths.values())
    out.config_texts = [backup.texts[kind] for kind in backup.paths]
    out.frames = "sysframe.va" in backup.paths

    def tok(kind: str, v: VaNumber, name: str, what: str, code=P211):
        if v.value is None:
            return Top(f"{name}'s {what} is not set in {kind} (********)", None, code)
        return Tok(v.value, (files[kind], v.start, v.end))

    # the frames: $MNUFRAME[1,n] / $MNUTOOL[1,n]
    path = backup.paths.get("sysframe.va")
    for var, table, given, label, code in (("$MNUFRAME", backup.uframes, uframes, "UF", P201),
                                           ("$MNUTOOL", backup.utools, utools, "UT", P203)):
        kind = "UFRAME" if label == "UF" else "UTOOL"
        for n, p in table.items():
            name, where = f"{kind}[{n}]", f"sysframe.va's {var}[1,{n}] (line {p.line})"
            if n < 1:
                continue
            xyzwpr = [c.value for c in p.xyzwpr] if p.kind == "cart" else []
            if p.kind != "cart" or None in xyzwpr:
                if n not in given:
                    out.why[name] = (f"{label} {n}: {where} is not initialised", code)
                continue
            xyzabc = np.array(xyzwpr[:3] + xyzwpr[3:][::-1], float)
            m = frame_to_matrix(xyzabc)
            if n in given:
                other = given[n] if kind == "UFRAME" else frame_to_matrix(np.array(given[n], float))
                turn = np.degrees(np.linalg.norm(rotation_vector(other[:3, :3].T @ m[:3, :3])))
                if np.linalg.norm(other[:3, 3] - m[:3, 3]) > AGREE or turn > AGREE:
                    del given[n]
                    six = matrix_to_frame(other)
                    stated = _xyzwpr(list(six[:3]) + list(six[3:][::-1]))
                    out.why[name] = (f"{label} {n}: the frame file (--frames) gives {stated} "
                                     f"and {where} {_xyzwpr(xyzwpr)}: which one the controller runs with is not known; "
                                     f"correct one, or leave [{_KEY[kind]}.{n}] out of the frame file to use the "
                                     "backup's", code)
                continue  # (the same frame: the frame file's)
            if kind in indirect or name in written:
                at = indirect.get(kind) or written.get(name)
                out.why[name] = (f"{label} {n} is set by a TP program read ({at}): what it holds before that is "
                                 f"known only at run time, not {where}", code)
                continue
            out.values[name] = Mat(m, f"{label} {n}") if kind == "UFRAME" else Six(tuple(float(x) for x in xyzabc),
                                                                                 f"{label} {n}")
            out.notes[name] = (f"{label} {n} is the backup's {var}[1,{n}] ({path}, line {p.line}), as the controller "
                               "held it when the backup was taken")

    # the registers: $POSREG[1,n], $NUMREG[n]
    for kind, table, prefix in (("posreg.va", backup.posregs, "PR"), ("numreg.va", backup.numregs, "R")):
        if kind not in backup.paths:
            continue
        path = backup.paths[kind]
        for n, entry in table.items():
            name = f"{prefix}[{n}]"
            line = entry.line if prefix == "PR" else entry[1]
            where = f"{kind} line {line}"
            if registers == "runtime":
                out.why[name] = (f"{name} holds what was set before the program runs (registers = \"runtime\": "
                                 f"the backup's value, {where}, is not used)", P211)
                continue
            if prefix in indirect or name in written:
                at = indirect.get(prefix) or written.get(name)
                out.why[name] = (f"{name} is set by a TP program read ({at}): what it holds before that is known "
                                 f"only at run time, not the backup's ({where})", P211)
                continue
            if prefix == "R":  # (a plain number: a constant wherever a program adds it, as a literal would be)
                value, _ = entry
                out.values[name] = Top(f"{name} is not set in {kind} (line {line})", None, P211) \
                    if value is None or value.value is None else value.value
            elif entry.kind == "uninit":
                out.values[name] = Top(f"{name} is not initialised in {kind} (line {line})", None, P211)
            elif entry.kind == "joint":
                out.values[name] = Rec("JOINTS", {}, None, name)
            else:
                fields = {k: tok(kind, v, name, w) for k, w, v in
                          zip(("X", "Y", "Z", "C", "B", "A"), "XYZWPR", entry.xyzwpr)}
                fields = {k: fields[k] for k in ("X", "Y", "Z", "A", "B", "C")}
                if entry.config:
                    fields["CONFIG"] = entry.config
                for axis, v in entry.ext.items():
                    fields[axis] = tok(kind, v, name, axis)
                if entry.ext:
                    fields["EXT"] = (f"{name} moves extended axes {', '.join(entry.ext)} too (a track…): without "
                                     "their kinematics its place in the robot base is not known")
                out.values[name] = Rec("POS", fields, None, name)
            out.notes[name] = (f"{name} is the backup's value ({path}, line {line}), as the controller held it when "
                               "the backup was taken: no TP program read sets it (where a KAREL program, vision or a "
                               "PLC does, set registers = \"runtime\")")
    return out


def _xyzwpr(values) -> str:
    return "[" + ", ".join(f"{v:g}" for v in values) + "]"
