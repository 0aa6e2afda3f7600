"""Corrected numbers → new program text and the stamp line (writing it: :mod:`postproc.core.atomic`).

Only the number tokens at the given spans change; every other character is copied.
New numbers keep the token's style: sign, leading zero or not, decimal count (at least
three decimals, i.e. µm resolution), exponent form.
"""
from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from decimal import Decimal

import numpy as np

from ..core.diagnostics import PostprocError

__all__ = ["decimal_range", "format_like", "format_many", "apply_edits", "splice", "check_disjoint", "insert_stamp", "stamp_line",
           "ORIENTATION_DECIMALS"]

MIN_DECIMALS = 3
# at most 1 nm: the model's correction is float32 (~1e-7 of a mm-size value) and a KRL REAL
# is 32-bit, so digits past this would be float noise, not the number's meaning
MAX_DECIMALS = 6
# KRL allows blanks between a sign and its number ('X - 5'): the reader's span covers both
# The decimals of an orientation form's numbers (frames.ORIENTATION_NAMES) as the unit (mm) of
# a length written alike (``decimal_range``): A,B,C degrees like mm (3 to 6 decimals: ≤ 0.0005°
# each), quaternion components and radians like metres (6 to 9: ≤ 5e-7 each, a rotation of at
# most 1.2e-4° for a quaternion and 5e-5° for a rotation vector; tests/test_orientation_dialects.py)
ORIENTATION_DECIMALS = {"abc": 1.0, "quaternion": 1000.0, "rotvec": 1000.0}
_TOKEN = re.compile(r"([+-]?)([ \t]*)(\d*)(?:\.(\d*))?(?:([eE])([+-]?)(\d+))?\Z")


def decimal_range(unit: float = 1.0) -> tuple[int, int]:
    """(fewest, most) decimals of a number written in units of ``unit`` mm (1000: metres):
    µm resolution at least, 1 nm at most, whatever the unit."""
    shift = int(round(math.log10(unit)))
    return MIN_DECIMALS + shift, MAX_DECIMALS + shift


def format_like(token: str, value: float, unit: float = 1.0) -> str:
    """``value`` (mm) written in the style of ``token`` (e.g. '1900.' → '1900.347', '.5' → '.512'),
    in units of ``unit`` mm, with MIN_DECIMALS to MAX_DECIMALS decimals at unit 1 (a token's
    longer tail is cut to 1 nm)."""
    m = _TOKEN.match(token)
    if m is None or not (m.group(3) or m.group(4)):
        raise ValueError(f"not a number token: {token!r}")
    fewest, most = decimal_range(unit)
    if unit != 1.0:
        value = value / unit
    sign, gap, whole, frac, e, esign, edigits = m.groups()
    decimals = min(max(fewest, len(frac or "")), most)
    if e:
        exponent = int(esign + edigits) if esign != "+" else int(edigits)
        # keep the exponent; add as many mantissa decimals as it takes to stay at µm resolution.
        # Decimal scales exactly: 10.0**exponent overflows or underflows for tokens like '0e400'
        mantissa = Decimal(value).scaleb(-exponent)
        digits = max(len(frac or ""), fewest + exponent, 0)
        if digits > most + exponent:  # a tail beyond 1 nm: cut, keeping a written '.'
            digits = max(most + exponent, 1 if frac else 0)
        body = f"{abs(mantissa):.{digits}f}"
        exp_text = e + (esign if esign else "") + str(abs(exponent)).zfill(len(edigits))
        if exponent < 0 and esign != "-":
            exp_text = e + "-" + str(abs(exponent)).zfill(len(edigits))
        out = body + exp_text
        negative = mantissa < 0 and Decimal(body) != 0  # float(body) underflows to 0 for '…e400'
    else:
        body = f"{abs(value):.{decimals}f}"
        negative = value < 0 and float(body) != 0.0  # never write '-0.000'
        if not whole and body.startswith("0."):
            body = body[1:]  # '.5' style: no leading zero
        out = body
    if negative:
        return "-" + (gap if sign else "") + out
    return ("+" + gap if sign == "+" else "") + out


_PLAIN = re.compile(r"-?\d+\.\d+\Z")
_ALL_PLAIN = re.compile(r"(?:-?\d+\.\d+\n)*-?\d+\.\d+")


def _format_plain(values: np.ndarray, decimals: np.ndarray, unit: float = 1.0) -> list[str]:
    """'%.{d}f' per value, one format string per distinct decimal count; never '-0.000'."""
    decimals = np.clip(decimals, *decimal_range(unit))
    # values that round to zero are written as zero: no '-0.000'
    values = np.where(np.abs(values) < 0.5 * 10.0 ** -decimals, 0.0, values)
    kinds = np.flatnonzero(np.bincount(decimals))  # (np.unique: it imports numpy.ma, 8 ms of a short run)
    if len(kinds) == 1:
        fmt = f"%.{int(kinds[0])}f"
        return [fmt % v for v in values.tolist()]
    out: list[str] = [""] * len(values)
    for d in kinds.tolist():
        idx = np.flatnonzero(decimals == d)
        fmt = f"%.{d}f"
        for i, v in zip(idx.tolist(), values[idx].tolist()):
            out[i] = fmt % v
    return out


def format_many(tokens: Sequence[str], values: np.ndarray, unit: float = 1.0) -> list[str]:
    """``format_like`` over many tokens (``values`` in mm, written in units of ``unit`` mm).
    The common CAM case (every token plain, like '-12.5' or '880.000') is checked with one
    regex over all tokens and formatted in bulk."""
    values = np.asarray(values, dtype=np.float64)
    if not len(tokens):
        return []
    if _ALL_PLAIN.fullmatch("\n".join(tokens)):
        chars = np.array(tokens)
        decimals = np.char.str_len(chars) - np.char.find(chars, ".") - 1
        return _format_plain(values / unit, decimals, unit)
    # a mix: the plain tokens in bulk all the same, the others one by one
    plain = [i for i, token in enumerate(tokens) if _PLAIN.match(token)]
    out = [format_like(token, value, unit) if not _PLAIN.match(token) else "" for token, value in zip(tokens, values.tolist())]
    if plain:
        decimals = np.array([len(tokens[i]) - tokens[i].index(".") - 1 for i in plain])
        for i, text in zip(plain, _format_plain(values[plain] / unit, decimals, unit)):
            out[i] = text
    return out


def splice(text: str, start: int, starts: list[int], ends: list[int], replacements: Sequence[str]) -> str:
    """``text[start:ends[-1]]`` with each ``text[starts[i]:ends[i]]`` replaced by
    ``replacements[i]``; the spans are sorted, do not overlap and begin at or after ``start``."""
    pieces: list[str] = [""] * (2 * len(starts))
    pieces[0::2] = [text[a:b] for a, b in zip([start, *ends[:-1]], starts)]
    pieces[1::2] = replacements
    return "".join(pieces)


def check_disjoint(starts: np.ndarray, ends: np.ndarray) -> None:
    """Sorted spans must not overlap: two edits of one token would corrupt it."""
    if np.any(starts[1:] < ends[:-1]):
        raise PostprocError("internal error: overlapping number spans")


def apply_edits(text: str, starts: np.ndarray, ends: np.ndarray, replacements: Sequence[str]) -> str:
    """Replace ``text[starts[i]:ends[i]]`` by ``replacements[i]``; spans must not overlap."""
    if len(starts) == 0:
        return text
    order = np.argsort(starts, kind="stable")
    starts, ends = np.asarray(starts)[order], np.asarray(ends)[order]
    check_disjoint(starts, ends)
    body = splice(text, 0, starts.tolist(), ends.tolist(), [replacements[i] for i in order.tolist()])
    return body + text[int(ends[-1]):]


def stamp_line(comment: str, prefix: str, model_name: str, sha256: str) -> str:
    return f"{comment} {prefix} {model_name} {sha256[:12]}"


BOM = "\xef\xbb\xbf"  # a UTF-8 byte order mark as the latin-1 text holds it


def insert_stamp(text: str, stamp: str, newline: str, after_headers: str | None = None) -> str:
    """Insert ``stamp`` as a line of its own: after the leading lines that start with
    ``after_headers`` (KRL's '&ACCESS'… lines must stay first), else at the top (after a UTF-8
    byte order mark, which stays the file's first bytes)."""
    pos = len(BOM) if text.startswith(BOM) else 0
    if after_headers:
        while pos < len(text) and text.startswith(after_headers, pos):
            nl = text.find("\n", pos)
            if nl < 0:  # headers only, no final newline
                return text + newline + stamp
            pos = nl + 1
    return text[:pos] + stamp + newline + text[pos:]


@dataclass
class _Inserts:
    """The X/Y/Z components to write into partial aggregates: where (``at``, an offset in the
    text), for which row of the file's targets and axis, and how (the aggregate's style)."""

    at: np.ndarray
    row: np.ndarray
    axis: np.ndarray
    before: list[str]  # text before the name (a separator when inserted after a component)
    names: list[str]
    gaps: list[str]  # between the name and the number
    like: list[str]  # the neighbour's number token, whose style the number takes
    after: list[str]  # text after the number (a separator when inserted before a component)

    def text(self, which: np.ndarray, values: np.ndarray) -> list[str]:
        return [self.before[k] + self.names[k] + self.gaps[k] + format_like(self.like[k], v) + self.after[k]
                for k, v in zip(which.tolist(), values.tolist())]


_SEPARATOR = re.compile(r"[ \t]*,[ \t]*")


def fill_partial(text: str, starts: np.ndarray, ends: np.ndarray) -> _Inserts:
    """Where and how to write the X/Y/Z that aggregates leave out (``starts``/``ends`` [n, 3]
    their number tokens' spans, -1 where absent; at least one present per row): a missing
    component goes before the next written one (``{Z 1250}`` → ``{X …,Y …,Z 1250}``), or after
    the last (``{X 1}`` → ``{X 1,Y …,Z …}``), with the aggregate's separator (``,`` or ``, ``),
    the case of its names, the blanks between name and number, and its numbers' style.
    Only rows with a missing component are looked at (one Python step each)."""
    out = _Inserts(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64), [], [], [], [], [])
    partial = np.flatnonzero((starts < 0).any(axis=1) & (starts >= 0).any(axis=1))
    at, row, axis = [], [], []
    for r in partial.tolist():
        present = [k for k in range(3) if starts[r, k] >= 0]
        names, gaps = {}, {}
        for k in present:
            j = int(starts[r, k]) - 1
            while j >= 0 and text[j] in " \t":
                j -= 1
            names[k] = j  # offset of the component's name (one letter X/Y/Z)
            gaps[k] = text[j + 1:int(starts[r, k])]
        # the separator: between two written components, else after the last one, else ','
        sep = next((m.group() for m in (_SEPARATOR.match(text, int(ends[r, k])) for k in present) if m), ",")
        k0 = present[0]
        upper = text[names[k0]].isupper()
        for k in range(3):
            if starts[r, k] >= 0:
                continue
            later = [j for j in present if j > k]
            name = "XYZ"[k] if upper else "xyz"[k]
            if later:
                j = later[0]
                at.append(names[j]), out.before.append(""), out.after.append(sep)
            else:
                j = present[-1]
                at.append(int(ends[r, j])), out.before.append(sep), out.after.append("")
            row.append(r), axis.append(k)
            out.names.append(name), out.gaps.append(gaps[j]), out.like.append(text[int(starts[r, j]):int(ends[r, j])])
    out.at, out.row, out.axis = (np.array(a, np.int64) for a in (at, row, axis))
    return out
