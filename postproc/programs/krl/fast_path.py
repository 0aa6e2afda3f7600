"""The shape cache and the accelerated reading of hot (literal target) lines."""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
from lark import Token, Tree
from lark.exceptions import UnexpectedInput

from ...core.diagnostics import P103, PostprocError, line_col
from ..ir import MOTION_INDEX as _MOTION
from ..model import STAMP_PREFIX
from .lower import _AXIS_KEYS, _KIND_OF
from .lower import mark_brace as _mark_brace
from .syntax import _FOLD, _MALFORMED, _NUM, SHAPE_RE, MalformedNumber, parser

_COMP = {k: i for i, k in enumerate(("X", "Y", "Z", "A", "B", "C"))}
_EXTERNAL_KEYS = frozenset(f"E{k}" for k in range(1, 7))


class _Shape:
    """What the parse of one line shape says. ``kind``: 'blank', 'hot' (a motion whose
    targets are literal Cartesian aggregates: read vectorised) or 'stmt'."""

    __slots__ = ("text", "kind", "tree", "ph", "phidx", "names", "name_paths", "plan", "fold", "error", "fcalls")

    def __init__(self, text):
        self.text = text
        ms = list(SHAPE_RE.finditer(text))
        self.ph = [m.start() for m in ms]  # every placeholder, in order (the line's "slots")
        self.phidx = {p: j for j, p in enumerate(self.ph)}
        self.names = [m.start() for m in ms if m.group(1) is None]  # those inside names
        self.name_paths = None  # where in the tree those names are (on first use)
        self.kind = "stmt"
        self.tree = None
        self.plan = None
        self.fold = 0
        self.error = None
        self.fcalls = False  # the statement calls a function in an expression (calls.expression_calls)


@dataclass
class _Plan:
    """How to read the targets of a hot line from its numbers: per target row, the slot
    (index among the line's numbers) of each of X…C, its sign and the distance from the
    sign to the digits, the ``{`` position in the shape, motion index, chain flag."""

    slots: np.ndarray  # [R, 6] int, -1 = not written
    neg: np.ndarray  # [R, 6] bool
    gap: np.ndarray  # [R, 6] int, chars from sign to number (0 = unsigned)
    brace: list  # [R] shape positions of '{'
    motion: list  # [R]
    chain: list  # [R] bool: does the row become the current position (CIRC aux: no)
    spl: bool  # an SPL segment (must stand inside SPLINE … ENDSPLINE)
    ph: list  # placeholder positions in the shape
    free: list = ()  # slots that carry their own sign (accelerator alternatives)
    names: list = ()  # slots that are the digits ending a name
    st: np.ndarray = None  # [R, 2] int, slots of S and T (unsigned numbers), -1 = not written


def _number_slot(expr, shape: _Shape):
    """(slot, negative, gap) when ``expr`` is a literal number (optionally signed)."""
    if expr.data == "number":
        return shape.phidx[expr.children[0].start_pos], False, 0
    if expr.data == "signed" and expr.children[1].data == "number":
        sign = expr.children[0]
        num = expr.children[1].children[0]
        return shape.phidx[num.start_pos], sign == "-", num.start_pos - sign.start_pos
    return None


def _hot_aggregate(agg, shape):
    """Slots of a literal Cartesian aggregate (or None when it is not one)."""
    ch = agg.children
    typ = None
    if ch and isinstance(ch[0], Token):
        typ = ch[0].upper()
        ch = ch[1:]
    keys = {}
    for item in ch:
        if item is None:
            continue
        name = item.children[0].upper()
        keys[name] = item.children[-1]
    if typ is not None and typ not in ("POS", "E6POS"):
        return None
    if typ is None and (keys.keys() & _AXIS_KEYS or not keys.keys() & {"X", "Y", "Z"}):
        return None
    if keys.keys() & _EXTERNAL_KEYS:  # (E1…E6: a track's or a turntable's position, read by the analysis)
        return None
    slots, neg, gap, st = [-1] * 6, [False] * 6, [0] * 6, [-1, -1]
    for k, v in keys.items():
        if k in _COMP:
            s = _number_slot(v, shape)
            if s is None:
                return None  # the interpreter reports it
            slots[_COMP[k]], neg[_COMP[k]], gap[_COMP[k]] = s
        elif k in ("S", "T"):
            s = _number_slot(v, shape)
            if s is None or s[1] or s[2]:
                return None  # 'B010', a sign, an expression: the interpreter reads it
            st[k == "T"] = s[0]
    if all(s < 0 for s in slots[:3]):
        return None
    return slots, neg, gap, agg.meta_brace, st


def _analyse(shape: _Shape) -> None:
    """Parse ``shape.text`` and decide how lines of this shape are read."""
    text = shape.text
    stripped = text.strip()
    if not stripped:
        shape.kind = "blank"
        return
    if stripped.startswith(";"):
        # a comment line: folds matter (balance), nothing else does
        m = _FOLD.match(text)
        if m:
            shape.fold = -1 if m.group(1) else 1
        shape.kind = "fold" if shape.fold else ("stamp" if STAMP_PREFIX in text else "blank")
        return
    try:
        tree = parser().parse(text)
    except UnexpectedInput as exc:
        shape.kind = "error"
        shape.error = exc
        return
    if _MALFORMED.search(text) is not None:  # (rare: only then the tree's numbers are looked at)
        numbers = {t.start_pos for t in tree.scan_values(lambda v: isinstance(v, Token) and v.type == "NUMBER")}
        bad = next((m.start() for m in _MALFORMED.finditer(text) if m.start() in numbers), None)
        if bad is not None:  # a number in the code, not in a comment or a string
            shape.kind = "error"
            shape.error = MalformedNumber(bad)
            return
    shape.tree = tree
    shape.fcalls = next(tree.find_data("fcall"), None) is not None
    stmt = None
    comment = None
    for c in tree.children:
        if isinstance(c, Tree):
            stmt = c
        elif isinstance(c, Token) and c.type == "COMMENT":
            comment = c
    if comment is not None:
        m = _FOLD.match(text[comment.start_pos:])
        if m:
            shape.fold = -1 if m.group(1) else 1
    if stmt is None:
        shape.kind = "fold" if shape.fold else "blank"
        return
    if shape.fold or (comment is not None and STAMP_PREFIX in comment):
        return
    if stmt.data not in ("move", "circ"):
        return
    kw = stmt.children[0].upper()
    if kw.endswith("_REL"):
        return
    tail = stmt.children[-1]
    for item in tail.children:
        if isinstance(item, Tree) and item.data == "with_item":
            root = item.children[0]
            while root.data in ("member", "index"):
                root = root.children[0]
            if root.data == "name" and root.children[0].upper() in ("$BASE", "$TOOL", "$ROBROOT", "$IPO_MODE", "$LOAD"):
                return
    if stmt.data == "move":
        ops = [(stmt.children[1], _MOTION[_KIND_OF[kw]], True)]
    else:
        s = "SCIRC" if kw.startswith("S") else "CIRC"
        ops = [(stmt.children[1], _MOTION[s + "-aux"], False), (stmt.children[2], _MOTION[s + "-end"], True)]
    rows = []
    for expr, motion, chain in ops:
        if not (isinstance(expr, Tree) and expr.data == "aggregate"):
            return
        _mark_brace(expr, text)
        hot = _hot_aggregate(expr, shape)
        if hot is None:
            return
        rows.append((hot, motion, chain))
    shape.plan = _Plan(
        slots=np.array([r[0][0] for r in rows], dtype=np.int64),
        neg=np.array([r[0][1] for r in rows], dtype=bool),
        gap=np.array([r[0][2] for r in rows], dtype=np.int64),
        brace=[r[0][3] for r in rows],
        motion=[r[1] for r in rows],
        chain=[r[2] for r in rows],
        spl=kw == "SPL",
        ph=shape.ph,
        names=[shape.phidx[p] for p in shape.names],
        st=np.array([r[0][4] for r in rows], dtype=np.int64),
    )
    shape.kind = "hot"


def _name_paths(tree, names) -> list:
    """Child-index paths to the tokens of ``tree`` that hold a name placeholder."""
    out = []

    def walk(node, path):
        for i, c in enumerate(node.children):
            if isinstance(c, Token):
                if c.type in ("NAME", "ENUM", "BITS") and any(c.start_pos <= p < c.end_pos for p in names):
                    out.append(path + (i,))
            elif c is not None:
                walk(c, path + (i,))

    walk(tree, ())
    return out


class _HotRows:
    """Columns of the targets read from hot lines (vectorised), appended chunk by chunk."""

    def __init__(self):
        self.parts = []

    def add(self, plan: _Plan, fi: int, line0: np.ndarray, start: np.ndarray, cols: list, key0: int,
            where=None) -> None:
        """``line0``: 0-based line numbers, ``start``: line start offsets, ``cols[j]``: the
        j-th number string of each line (a sequence, one per line)."""
        n = len(line0)
        if n == 0:
            return
        used = sorted({int(s) for s in plan.slots.ravel() if s >= 0})
        brace_slots = [sum(1 for p in plan.ph if p < b) for b in plan.brace]
        need_len = max([int(plan.slots.max()) + 1] + brace_slots)  # (X..C: A/B/C spans for --orientation)
        lens = {j: np.fromiter(map(len, cols[j]), np.int64, n) for j in range(need_len)}
        vals = {j: np.array(cols[j], dtype=np.float64) for j in used}
        ph = np.array(plan.ph, dtype=np.int64)
        for j, v in vals.items():
            if not np.isfinite(v).all():  # 1E999: P103 at the token
                k = int(np.flatnonzero(~np.isfinite(v))[0])
                off = int(start[k]) + int(ph[j]) + sum(len(cols[q][k]) - 1 for q in range(j))
                path, text = where
                raise PostprocError(f"'{cols[j][k]}' is not a finite number", path, *line_col(text, off), P103)
        # offset of slot j in its line: ph[j] + Σ_{i<j} (len_i − 1)
        shift = [np.zeros(n, np.int64)]
        for j in range(need_len):
            shift.append(shift[-1] + lens[j] - 1)
        for r in range(len(plan.motion)):
            pose = np.full((n, 6), np.nan)
            written = np.zeros((n, 6), bool)
            spans = np.full((n, 12), -1, np.int64)
            for c in range(6):
                j = int(plan.slots[r, c])
                if j < 0:
                    continue
                v = vals[j]
                pose[:, c] = -v if plan.neg[r, c] else v
                written[:, c] = True
                s = start + ph[j] + shift[j]
                spans[:, 2 * c] = s - plan.gap[r, c]
                spans[:, 2 * c + 1] = s + lens[j]
            config = np.full((n, 2), -1, np.int16)
            for c in range(2):
                j = int(plan.st[r, c])
                if j >= 0:
                    config[:, c] = _config_column(cols[j], n)
            b = plan.brace[r]
            col = b + 1 + shift[brace_slots[r]]
            self.parts.append(dict(
                key=key0 + line0 * 4 + r, pose=pose, written=written, spans=spans,
                file=np.full(n, fi, np.int32), line=(line0 + 1).astype(np.int32), col=col.astype(np.int32),
                motion=np.full(n, plan.motion[r], np.int8), chain=np.full(n, plan.chain[r]),
                spl=np.full(n, plan.spl), config=config,
            ))


def _config_column(strings, n: int) -> np.ndarray:
    """S or T numbers as written → int16, -1 where not a whole number in 0…32767."""
    with np.errstate(over="ignore", invalid="ignore"):
        v = np.array(strings, dtype=np.float64).reshape(n)
        ok = np.isfinite(v) & (v == np.round(v)) & (v >= 0) & (v <= 32767)
    return np.where(ok, v, -1).astype(np.int16)


class _Accel:
    """One regex matching, line by line, the frequent hot shapes with their numbers as
    groups; any other line falls into the last group and goes to the interpreter.

    Alternatives are *sign-free* shapes (``_generalise``): a target component may carry
    a sign or not, so ``{X 1,Y -2}`` and ``{X -1,Y 2}`` share one alternative."""

    MAX = 8

    def __init__(self, alts: list):
        self.alts = alts[: self.MAX]  # (sign-free text, plan)
        parts_all, self.first = [], []
        g = 1
        for text, plan in self.alts:
            parts, last = [], 0
            free, names = set(plan.free), set(plan.names)
            for j, p in enumerate(plan.ph):
                parts.append(re.escape(text[last:p]))
                parts.append(r"(\d+)" if j in names else "([-+]?" + _NUM + ")" if j in free else "(" + _NUM + ")")
                last = p + 1
            parts.append(re.escape(text[last:]))
            parts_all.append("".join(parts))
            self.first.append(g)
            g += len(plan.ph)
        self.fallback = g
        self.regex = re.compile("^(?:" + "|".join(parts_all) + r"|([^\n]*))$", re.M)


def _generalise(shape: _Shape):
    """(sign-free text, plan) of a hot shape: the sign written before a target component
    moves into the number slot (the slot then matches ``[-+]?number``)."""
    plan = shape.plan
    text = shape.text
    free, drop = set(), set()
    for r in range(len(plan.motion)):
        for c in range(6):
            j = int(plan.slots[r, c])
            if j < 0:
                continue
            if plan.gap[r, c] == 1:
                drop.add(plan.ph[j] - 1)
                free.add(j)
            elif plan.gap[r, c] == 0:
                free.add(j)
    out, keep = [], []
    for i, ch in enumerate(text):
        if i not in drop:
            keep.append(i)
            out.append(ch)
    newpos = {old: new for new, old in enumerate(keep)}
    ph = [newpos[p] for p in plan.ph]
    brace = [newpos[b] for b in plan.brace]
    neg = plan.neg.copy()
    gap = plan.gap.copy()
    for r in range(len(plan.motion)):
        for c in range(6):
            if int(plan.slots[r, c]) in free:
                neg[r, c] = False
                gap[r, c] = 0
    g = _Plan(slots=plan.slots, neg=neg, gap=gap, brace=brace, motion=plan.motion, chain=plan.chain,
              spl=plan.spl, ph=ph, names=plan.names, st=plan.st)
    g.free = sorted(free)
    return "".join(out), g


# lines read by the interpreter before the first accelerated chunk, to learn the hot shapes (a
# CAM program has a few; a shape learned later joins the regex as it comes): few, since a
# streamed program reads every chunk of ~16k lines as a program of its own
LEARN_LINES = 256


class FastPath:
    """The shape cache and the accelerated reading of hot (literal target) lines. (methods of the Reader)"""

    CHUNK = 1 << 17  # characters per vectorised chunk: small enough that its strings stay in cache

    def scan_accelerated(self, text: str, nlines: int, hot_lines) -> None:
        """Learn the shapes of the first lines with the interpreter, then read chunks with one
        regex over the frequent hot shapes; lines it does not take go to the interpreter."""
        from operator import itemgetter

        starts = self.starts
        learn = LEARN_LINES
        self.scan_lines(range(learn), hot_lines)
        counts, plans = {}, {}

        def learn_from(entries):
            dirty = False
            for sh, entry in entries.items():
                if sh.plan is None:
                    continue
                g = _generalise(sh)
                if g[0] not in plans:
                    plans[g[0]] = g[1]
                    dirty = True
                counts[g[0]] = counts.get(g[0], 0) + len(entry[0])
            return dirty

        learn_from(hot_lines)
        accel, dirty, i = None, True, learn
        while i < nlines:
            if dirty:
                ranked = sorted(counts, key=counts.get, reverse=True)
                new = _Accel([(t, plans[t]) for t in ranked])
                if accel is None or [a[0] for a in new.alts] != [a[0] for a in accel.alts]:
                    accel = new
                dirty = False
            a = int(starts[i])
            j = int(np.searchsorted(starts, a + self.CHUNK, "left"))
            j = min(max(j, i + 1), nlines)
            b = int(starts[j]) if j < len(starts) else len(text)
            rows = accel.regex.findall(text[a:b])
            n = j - i
            if len(rows) < n or not accel.alts:  # (never: one match per line) line by line
                self.scan_lines(range(i, j), hot_lines)
                i = j
                continue
            del rows[n:]
            cols = list(zip(*rows))
            del rows
            fallback = cols[accel.fallback - 1]
            line0 = np.arange(i, j, dtype=np.int64)
            is_hot = np.zeros(n, bool)
            for (gtext, plan), g in zip(accel.alts, accel.first):
                m = np.fromiter(map(bool, cols[g - 1]), bool, n)
                if not m.any():
                    continue
                is_hot |= m
                sel = np.flatnonzero(m)
                if len(sel) == n:
                    sub = [cols[g - 1 + q] for q in range(len(plan.ph))]
                else:
                    pick = itemgetter(*sel.tolist()) if len(sel) > 1 else (lambda c, k=int(sel[0]): (c[k],))
                    sub = [pick(cols[g - 1 + q]) for q in range(len(plan.ph))]
                self.hot.add(plan, self.fi, line0[sel], starts[line0[sel]], sub, self.key0, (self.path, self.text))
                counts[gtext] += len(sel)
            del cols
            rest = np.flatnonzero(~is_hot)
            if len(rest):
                found = {}
                for k in rest.tolist():
                    li = i + k
                    self.line_at(li, int(starts[li]), fallback[k], found)
                for sh, entry in found.items():
                    e = hot_lines.setdefault(sh, ([], [], []))
                    for q in range(3):
                        e[q].extend(entry[q])
                if sum(len(e[0]) for e in found.values()) > 64:
                    dirty = learn_from(found) or dirty
                else:
                    learn_from(found)
            i = j
