"""RAPID text laid out again the ways a controller or an editor writes the same program (issue
36's property: the analysis must not depend on the layout). Each function returns the program
with only whitespace, line endings and argument names changed:

* :func:`crlf`: CRLF line endings (a controller's backup);
* :func:`join_heads`: a statement joined onto the line of the THEN, ELSE, DO or label before it;
* :func:`break_lists`: argument lists, aggregates and routine headers broken after each comma;
* :func:`by_name`: the required arguments of MoveL/MoveJ/MoveC/MoveAbsJ given by name;
* :func:`flat`: the whole module on one line.

Strings and comments are left alone (a line holding either is not changed by the last three).
"""
from __future__ import annotations

import re

__all__ = ["crlf", "join_heads", "break_lists", "by_name", "flat", "LAYOUTS", "top_level_split"]

_HEAD = re.compile(r"(?:\bTHEN|\bELSE|\bDO|^[ \t]*[A-Za-z_]\w*[ \t]*:)[ \t]*$", re.I)
_BLOCK = re.compile(r"[ \t]*(MODULE|ENDMODULE|PROC|ENDPROC|FUNC|ENDFUNC|TRAP|ENDTRAP|LOCAL|IF|ELSEIF|ELSE|ENDIF|FOR|"
                    r"ENDFOR|WHILE|ENDWHILE|TEST|CASE|DEFAULT|ENDTEST|ERROR|UNDO|BACKWARD|RECORD|ENDRECORD)\b", re.I)
_PARAMS = {"MOVEL": ("ToPoint", "Speed", "Zone", "Tool"), "MOVEJ": ("ToPoint", "Speed", "Zone", "Tool"),
           "MOVEC": ("CirPoint", "ToPoint", "Speed", "Zone", "Tool"),
           "MOVEABSJ": ("ToJointPos", "Speed", "Zone", "Tool")}


def _plain(line: str) -> bool:
    return '"' not in line and "!" not in line


def crlf(text: str) -> str:
    return text.replace("\r\n", "\n").replace("\n", "\r\n")


def join_heads(text: str) -> str:
    """Each one-statement line after a line ending with THEN, ELSE, DO or a label, joined onto it."""
    lines = text.split("\n")
    out: list[str] = []
    k = 0
    while k < len(lines):
        line = lines[k]
        nxt = lines[k + 1] if k + 1 < len(lines) else ""
        if (_plain(line) and _plain(nxt) and _HEAD.search(line.rstrip("\r")) and nxt.strip().endswith(";")
                and nxt.count(";") == 1 and not _BLOCK.match(nxt)):
            out.append(line.rstrip("\r").rstrip() + " " + nxt.strip())
            k += 2
            continue
        out.append(line)
        k += 1
    return "\n".join(out)


def break_lists(text: str) -> str:
    """A line break after every comma of a statement or a routine header (outside strings and comments)."""
    out = []
    for line in text.split("\n"):
        body = line.rstrip("\r")
        if _plain(body) and "," in body and (body.rstrip().endswith(";") or re.match(r"\s*(LOCAL\s+)?(PROC|FUNC)\b", body, re.I)):
            cr = "\r" if line.endswith("\r") else ""
            line = body.replace(",", "," + cr + "\n        ") + cr
        out.append(line)
    return "\n".join(out)


def top_level_split(args: str) -> list[str]:
    """``a, [b, c], f(d, e)`` → the arguments at bracket depth 0."""
    parts, depth, start = [], 0, 0
    for i, ch in enumerate(args):
        if ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(args[start:i])
            start = i + 1
    parts.append(args[start:])
    return parts


_MOVE = re.compile(r"^([ \t]*)(MoveL|MoveJ|MoveC|MoveAbsJ)([ \t]+)([^;]*);([ \t\r]*)$", re.I)


def by_name(text: str) -> str:
    """MoveL p1, v100, fine, tool0\\WObj:=w; → MoveL ToPoint:=p1, Speed:=v100, Zone:=fine, Tool:=tool0\\WObj:=w;"""
    out = []
    for line in text.split("\n"):
        m = _MOVE.match(line)
        if m and _plain(line) and ":=" not in m.group(4).split("\\")[0]:
            names = _PARAMS[m.group(2).upper()]
            args = top_level_split(m.group(4))
            if len(args) == len(names) and not any(a.strip().startswith("\\") for a in args):
                named = ",".join(f"{n}:={a.strip()}" for n, a in zip(names, args))
                line = f"{m.group(1)}{m.group(2)}{m.group(3)}{named};{m.group(5)}"
        out.append(line)
    return "\n".join(out)


def flat(text: str) -> str:
    """The whole module on one line (where it holds no comment, which would run to its end)."""
    if "!" in text:
        return text
    return " ".join(line.strip() for line in text.replace("\r\n", "\n").split("\n") if line.strip()) + "\n"


def _all(text: str) -> str:
    return crlf(break_lists(by_name(join_heads(text))))


LAYOUTS = {"crlf": crlf, "join_heads": join_heads, "break_lists": break_lists, "by_name": by_name, "flat": flat,
           "all": _all}
