"""The mutation fuzzer of `postproc compensate` (its engine: corpus, mutations, the outcome
check); ``benchmarks/fuzz.py`` runs it at full size, ``tests/test_fuzz.py`` small.

Takes every sample program (samples/krl/*: a .src with its .dat; samples/poses/*;
samples/rapid/*: ABB RAPID modules; samples/urscript/*: URScript; samples/fanuc/*.ls with the frame
file beside them), or those of one --dialect, applies
random byte, token and line mutations (delete, duplicate, swap, insert garbage or a
keyword, replace a number by an edge case, truncate, change line endings) and compensates
each mutant with a constant-offset model. Every mutant must end in one of two ways:

* exit 0 (or 1: targets left as written), and the output round-trips: re-reading it gives the same targets (count, file,
  line, column, frame, motion), every byte outside the X/Y/Z number tokens is the mutant's
  (apart from the one stamp line), and every number moved by exactly the model's offset
  taken into the target's base (Rᵀ·offset), or not at all for targets left as they were;
* exit 2 with one `path:line:col: CODE message` (or `path: CODE message`) line on stderr,
  the previous output files byte-identical, and no temporary file left behind. P190 (the
  last check before writing found a span or a replacement that is not the number it
  should be) is clean for the user but a bug in a reader or the formatter: counted apart.

Anything else is a crash (a traceback, "internal error", another exit code, a malformed
message), a wrong output, or a hang (over --timeout seconds). Mutants run in-process through
``postproc.cli.main`` for speed; --subprocess of them also through `python -m postproc`.
With ``keep``, the offending mutants are saved for reproduction.
"""
from __future__ import annotations

import contextlib
import io
import re
import shutil
import signal
import subprocess
import sys
import tempfile
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.diagnostics import P190
from ..core.resources import sample_path

OFFSET = (0.3, -0.2, 0.1)  # mm, the constant-offset model's error in the robot base frame
MESSAGE = re.compile(r"(?P<path>.+?):(?:(?P<line>\d+):(?P<col>\d+):)? (?P<code>P\d{3}) (?P<message>.+)")

# Pieces a mutation may insert: KRL and pose-list syntax, and numbers that break naive readers.
KEYWORDS = [
    "LIN", "PTP", "CIRC", "SPTP", "SLIN", "SCIRC", "SPL", "SPLINE", "ENDSPLINE", "DEF", "END", "DEFDAT",
    "ENDDAT", "DEFFCT", "ENDFCT", "DECL", "GLOBAL", "PUBLIC", "E6POS", "POS", "FRAME", "E6AXIS", "AXIS",
    "$BASE", "$TOOL", "$ROBROOT", "$NULLFRAME", "BASE_DATA[1]", "TOOL_DATA[2]", "BAS(#BASE,1)",
    "BAS(#TOOL,1)", ";FOLD ", ";ENDFOLD", "{", "}", ",", ":", "=", "[", "]", "(", ")", "X ", "Y ", "Z ",
    "A ", "B ", "C ", "S ", "T ", "E1 ", "'B010'", "'H2F'", '"text"', '"', "'", ";", "&ACCESS RVP", "&REL 3",
    "C_DIS", "C_VEL", "C_PTP", "WITH $VEL={CP 0.2}", "LIN_REL", "PTP_REL", "#BASE", "#TOOL", "INV_POS(",
    "XP1", "P[3]", "IF", "ENDIF", "FOR", "ENDFOR", "CA 90", "\n", "\r\n", "\r", "\t", " ", "  ",
    "x", "y", "z", "a", "b", "c", "name", "#", "//", "nan", "inf", "-", "+", ".", "e", "E5",
    "; postproc: compensated with model",
    # ABB RAPID
    "MODULE m", "ENDMODULE", "PROC main()", "ENDPROC", "MoveL", "MoveJ", "MoveC", "MoveAbsJ", "Offs(p10,0,0,5)",
    "RelTool(", "robtarget", "CONST", "PERS", "VAR", "tooldata", "wobjdata", "\\WObj:=", "wobj0", "tool0",
    ":=", "!", "[[", "]]", "9E+09", "{", "}", "[1,0,0,0]", "[0,0,0,0]", "TRUE", "FALSE", "v100", "fine", "z10",
    "! postproc: compensated with model",
    # URScript
    "def prog():", "end", "movel(", "movej(", "movep(", "movec(", "p[", "p[0.1,0.2,0.3,0,3.14,0]", "pose_trans(",
    "set_tcp(", "global ", "local ", "wp1", "wp1 = ", "if True:", "elif", "else:", "while False:", "thread t():",
    "a=1.2", "v=0.25", "[0,0,0,0,0,0]", "$ 1 \"x\"", "# postproc: compensated with model",
    # Fanuc LS
    "/PROG", "/ATTR", "/MN", "/POS", "/END", "P[1]", "PR[1]", "J ", "L ", "C ", ":", "GP1:", "GP2:", "UF : 1",
    "UT : 2", "UF : F", "CONFIG : 'N U T, 0, 0, 0'", "X =", "W =", "J1=", "mm", "deg", "Offset,PR[1]", "INC",
    "};", "   5:  ! postproc: compensated with model x 0123456789ab ;", "[uframe.1]", "[utool.1]", "xyzwpr = ",
]
NUMBERS = ["nan", "inf", "-inf", "1e999", "-1e999", "1e-400", "0e400", "1.5E+03", "-0.000", ".5", "5.", "+5",
           "1e308", "123456789012345678901234567890", "0.0000001", "-", ".", "1e", "1.2.3", "2000", "-2000",
           "99999", "1E+3", "0x10", "1_000"]
TOKEN = re.compile(rb"\s+|[A-Za-z_$][\w$]*|[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|.", re.S)
NUMBER = re.compile(rb"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\Z")


class Hang(BaseException):
    """Raised by the alarm: a BaseException so that the CLI's last-resort handler lets it through."""


@dataclass
class Sample:
    name: str
    files: dict[str, bytes]  # file name → bytes; the first is the one given to compensate
    config: dict[str, bytes] = field(default_factory=dict)  # $config.dat(s), given with --config


def corpus(root: Path | None = None) -> list[Sample]:
    """Every sample program: a KRL .src with its .dat (same stem), a lone .dat, a pose list.
    KRL samples come with the sample $config.dat (BASE_DATA / TOOL_DATA)."""
    root = sample_path("") if root is None else root
    samples = []
    krl = sorted((root / "krl").rglob("*")) if (root / "krl").is_dir() else []
    config = {p.name: p.read_bytes() for p in krl if p.name.lower() == "$config.dat"}
    by_stem: dict[str, list[Path]] = {}
    for path in krl:
        if path.suffix.lower() in (".src", ".dat") and not path.name.startswith("$"):
            by_stem.setdefault(str(path.relative_to(root / "krl").with_suffix("")).lower(), []).append(path)
    for stem, paths in sorted(by_stem.items()):
        paths.sort(key=lambda p: p.suffix.lower() != ".src")  # .src first
        samples.append(Sample(paths[0].name, {p.name: p.read_bytes() for p in paths}, dict(config)))
    for path in sorted((root / "poses").glob("*")):
        if path.suffix.lower() in (".csv", ".txt"):
            samples.append(Sample(path.name, {path.name: path.read_bytes()}))
    for path in sorted((root / "rapid").glob("*")) if (root / "rapid").is_dir() else []:
        if path.suffix.lower() in (".mod", ".prg", ".sys", ".modx"):
            samples.append(Sample(path.name, {path.name: path.read_bytes()}))
    for path in sorted((root / "urscript").glob("*")) if (root / "urscript").is_dir() else []:
        if path.suffix.lower() == ".script":
            samples.append(Sample(path.name, {path.name: path.read_bytes()}))
    fanuc = root / "fanuc"
    frames = {p.name: p.read_bytes() for p in sorted(fanuc.glob("*.toml"))} if fanuc.is_dir() else {}
    for path in sorted(fanuc.glob("*")) if fanuc.is_dir() else []:
        if path.suffix.lower() == ".ls":  # with the frame file (UF/UT), given as --config (= --frames)
            samples.append(Sample(path.name, {path.name: path.read_bytes()}, dict(frames)))
    return samples


# --------------------------------------------------------------------------- mutations


def _span(rng: np.random.Generator, n: int, longest: int = 24) -> tuple[int, int]:
    if n == 0:
        return 0, 0
    start = int(rng.integers(0, n))
    length = min(int(rng.geometric(0.25)), longest, n - start)
    return start, start + length


def _byte_op(data: bytes, rng: np.random.Generator) -> bytes:
    op = rng.choice(["delete", "duplicate", "swap", "garbage", "keyword", "truncate", "flip"])
    n = len(data)
    s, e = _span(rng, n)
    at = int(rng.integers(0, n + 1))
    if op == "delete":
        return data[:s] + data[e:]
    if op == "duplicate":
        return data[:at] + data[s:e] + data[at:]
    if op == "swap":
        s2, e2 = _span(rng, n)
        if e <= s2 or e2 <= s:
            (s, e), (s2, e2) = sorted([(s, e), (s2, e2)])
            return data[:s] + data[s2:e2] + data[e:s2] + data[s:e] + data[e2:]
        return data
    if op == "garbage":
        return data[:at] + rng.integers(0, 256, int(rng.integers(1, 9)), dtype=np.uint8).tobytes() + data[at:]
    if op == "keyword":
        return data[:at] + KEYWORDS[int(rng.integers(len(KEYWORDS)))].encode() + data[at:]
    if op == "truncate":
        return data[:at]
    if op == "flip" and n:  # one character for a neighbour of it: digits for digits, letters for letters
        i = int(rng.integers(0, n))
        return data[:i] + bytes([(data[i] + int(rng.choice([-1, 1]))) % 256]) + data[i + 1:]
    return data


def _token_op(data: bytes, rng: np.random.Generator) -> bytes:
    tokens = TOKEN.findall(data)
    if not tokens:
        return data
    op = rng.choice(["delete", "duplicate", "swap", "number", "keyword"])
    i = int(rng.integers(len(tokens)))
    if op == "delete":
        del tokens[i]
    elif op == "duplicate":
        tokens.insert(i, tokens[i])
    elif op == "swap":
        j = int(rng.integers(len(tokens)))
        tokens[i], tokens[j] = tokens[j], tokens[i]
    elif op == "number":
        numbers = [k for k, t in enumerate(tokens) if NUMBER.match(t)]
        if numbers:
            i = numbers[int(rng.integers(len(numbers)))]
            tokens[i] = NUMBERS[int(rng.integers(len(NUMBERS)))].encode()
    else:
        tokens[i] = KEYWORDS[int(rng.integers(len(KEYWORDS)))].encode()
    return b"".join(tokens)


def _line_op(data: bytes, rng: np.random.Generator) -> bytes:
    lines = data.splitlines(keepends=True)
    if not lines:
        return data
    op = rng.choice(["delete", "duplicate", "swap", "crlf", "lf", "no-final-newline"])
    i, j = int(rng.integers(len(lines))), int(rng.integers(len(lines)))
    if op == "delete":
        del lines[i]
    elif op == "duplicate":
        lines.insert(j, lines[i])
    elif op == "swap":
        lines[i], lines[j] = lines[j], lines[i]
    elif op == "crlf":
        lines[i] = lines[i].rstrip(b"\r\n") + b"\r\n"
    elif op == "lf":
        lines[i] = lines[i].rstrip(b"\r\n") + b"\n"
    else:
        lines[-1] = lines[-1].rstrip(b"\r\n")
    return b"".join(lines)


def mutate(sample: Sample, rng: np.random.Generator) -> Sample:
    """A copy of the sample with 1-3 mutations in one of its files ($config.dat included)."""
    files, config = dict(sample.files), dict(sample.config)
    where = files if not config or rng.random() < 0.85 else config
    name = list(where)[int(rng.integers(len(where)))]
    data = where[name]
    for _ in range(int(rng.integers(1, 4))):
        kind = rng.choice(["byte", "token", "line"], p=[0.4, 0.4, 0.2])
        data = {"byte": _byte_op, "token": _token_op, "line": _line_op}[kind](data, rng)
    where[name] = data
    return Sample(sample.name, files, config)


# --------------------------------------------------------------------------- one run


@dataclass
class Outcome:
    kind: str  # output | error | crash | wrong | hang
    detail: str = ""


def _run_inprocess(argv: list[str], timeout: float) -> tuple[int | str, str]:
    from ..cli import main

    def alarm(signum, frame):
        raise Hang()

    err = io.StringIO()
    previous = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, timeout)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code: int | str = main(argv)
    except Hang:
        code = "hang"
    except BaseException as exc:  # noqa: BLE001 - anything escaping main is a crash (or -v re-raised it)
        import traceback

        frame = traceback.extract_tb(exc.__traceback__)[-1]
        code = f"raised {type(exc).__name__}: {exc} at {Path(frame.filename).name}:{frame.lineno}"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    return code, err.getvalue()


def _run_subprocess(argv: list[str], timeout: float) -> tuple[int | str, str]:
    try:
        proc = subprocess.run([sys.executable, "-m", "postproc", *argv], capture_output=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return "hang", ""
    return proc.returncode, proc.stderr.decode("utf-8", "replace")


def _strip_stamp(text: str, stamp: str) -> str | None:
    """The text without the one stamp line postproc added (None if it is not there)."""
    ls = re.search(r"^ *\d+:  " + re.escape(stamp) + r" ;\r?\n", text, re.M)  # Fanuc LS: a remark at the end of /MN
    if ls:  # (which /ATTR's LINE_COUNT counts: one less without it)
        text = text[:ls.start()] + text[ls.end():]
        return re.sub(r"^(LINE_COUNT[ \t]*=[ \t]*)(\d+)", lambda m: f"{m.group(1)}{int(m.group(2)) - 1}", text,
                      count=1, flags=re.M)
    for newline in ("\r\n", "\n"):
        if stamp + newline in text:
            return text.replace(stamp + newline, "", 1)
    for newline in ("\r\n", "\n"):
        if text.endswith(newline + stamp):  # headers only, no final newline
            return text[: -len(newline + stamp)]
    return None


def _segments(text: str, spans: np.ndarray, cuts: list[tuple[int, int]] = ()) -> list[str]:
    """The text between the number tokens at ``spans`` [K, 2] (unique, present), without
    the ``cuts`` (components written into partial aggregates)."""
    items = sorted([(s, e, False) for s, e in spans.tolist()] + [(s, e, True) for s, e in cuts])
    out, piece, prev = [], "", 0
    for s, e, cut in items:
        piece += text[prev:s]
        prev = e
        if not cut:
            out.append(piece)
            piece = ""
    out.append(piece + text[prev:])
    return out


_SEP = re.compile(r"[ \t]*,[ \t]*")


def _inserted(text: str, spans: np.ndarray, filled: np.ndarray, present: np.ndarray) -> list[tuple[int, int]]:
    """Where the components filled in stand in ``text``: name, number and the separator that
    came with it (the one after it when a written component follows, else the one before)."""
    out = []
    for r, k in zip(*np.nonzero(filled)):
        s, e = (int(v) for v in spans[r, k])
        j = s - 1
        while j >= 0 and text[j] in " \t":
            j -= 1
        start = j  # the name's one letter
        if present[r, k + 1:].any():
            m = _SEP.match(text, e)
            out.append((start, m.end() if m else e))
        else:
            before = re.search(r"[ \t]*,[ \t]*\Z", text[max(0, start - 40):start])
            out.append((start - (len(before.group()) if before else 0), e))
    return out


def check_output(files: list[str], texts: list[str], outputs: list[str], model, offset=OFFSET,
                 config: list[str] | None = None) -> str | None:
    """Why ``outputs`` is not the mutant ``texts`` compensated by a constant-offset model
    (None when it is). ``files`` are the mutant's file names (messages and dialect),
    ``config`` the $config.dat texts it was compensated with."""
    from ..core import frames
    from ..programs import STAMP_PREFIX
    from ..programs.io import dialect_of, read_program

    dialect = dialect_of(files[0])
    before = read_program(files, texts, dialect, config=config)
    try:
        read_program(files, outputs, dialect, config=config)  # the output as written, stamp included
    except Exception as exc:  # noqa: BLE001
        return f"output does not re-read: {exc}"
    stamp = f"{before.comment} {STAMP_PREFIX} {model.name} {model.sha256[:12]}"
    stripped = [_strip_stamp(t, stamp) for t in outputs]
    a = before.targets
    moved = (a.frame >= 0) & np.isfinite(a.poses[:, :3]).all(axis=1)  # what compensate changes
    # targets whose S/T state another arm configuration than the model's one branch (P313: a mutated
    # angle can make one) stay as written: compensate's own rule, which this check does not model
    from ..compensation.findings import select_with_findings
    from ..core.diagnostics import P313
    from ..settings import Settings

    try:
        selection, _ = select_with_findings(before, model, Settings())
        moved[np.asarray(selection.left.get(P313, []), int)] = False
    except Exception:  # noqa: BLE001 (an error of the rules: compensate refused, exit 2, checked before)
        pass
    # rows the analysis holds (P217: their numbers are read elsewhere too) stay as written
    for rows in (getattr(before, "held", None) or {}).values():
        moved[np.asarray(rows, int)] = False
    unstamped = [index for index, text in enumerate(stripped) if text is None]
    for index in unstamped:
        stripped[index] = outputs[index]
    after = read_program(files, stripped, dialect, config=config)
    b = after.targets
    group = getattr(a, "group", None)
    if len(a) == len(b) and group is not None and (group >= 0).any() \
            and np.array_equal(a.spans[:, :, 0] >= 0, b.spans[:, :, 0] >= 0):
        # one set of numbers run more than once (a loop, copies): compensated at every run or,
        # where the runs need other numbers (P230), left as written at every run
        same = (np.nan_to_num(_values(texts, a, before.unit)) == np.nan_to_num(_values(stripped, b, before.unit)))
        for g in np.unique(group[group >= 0]):
            rows = group == g
            if same[rows].all():
                moved[rows] = False
    for index in range(len(stripped)):
        changed = bool(moved[a.file == index].any())
        if index in unstamped and changed:
            return f"{files[index]} has no stamp line"
        if index in unstamped and stamp in outputs[index]:
            return f"{files[index]}: a stamp line in a file in which no target was compensated"
    if len(a) != len(b):
        return f"{len(a)} targets before, {len(b)} after"
    # (not col: a longer number earlier on the line moves the aggregates after it)
    for column in ("file", "line", "frame", "motion"):
        if not np.array_equal(getattr(a, column), getattr(b, column)):
            return f"targets differ in {column}"
    # partial aggregates of compensated targets get their missing X/Y/Z written in
    present = a.spans[:, :, 0] >= 0
    filled = ~present & moved[:, None]
    if not np.array_equal(present | filled, b.spans[:, :, 0] >= 0):
        return "different X/Y/Z components present"
    for index in range(len(files)):
        rows = a.file == index
        sa = np.unique(a.spans[rows].reshape(-1, 2), axis=0)
        sa = sa[sa[:, 0] >= 0]
        sb = np.unique(b.spans[rows][present[rows]].reshape(-1, 2), axis=0)
        cuts = _inserted(stripped[index], b.spans, filled & rows[:, None], present)
        if _segments(texts[index], sa) != _segments(stripped[index], sb, cuts):
            return f"{files[index]}: bytes outside the number tokens (and the components filled in) changed"
    # every present number moved by the offset taken into its base, or not at all
    expected = np.zeros((len(a), 3))
    for f in np.unique(a.frame[moved]):
        rows = moved & (a.frame == f)
        expected[rows] = frames.rotate_vectors(frames.inverse(before.frames[f].base), np.asarray(offset, float))
    if group is not None and a.offset is not None and (group >= 0).any():
        # a point compensated for its runs at the point itself, its runs at an offset moving with it (P231):
        # every run's numbers change as the point's own runs' do
        at_point = ~(np.abs(a.offset) > 1e-9).any(axis=1)
        for g in np.unique(group[moved & (group >= 0)]):
            rows = np.flatnonzero(moved & (group == g))
            own = rows[at_point[rows]]
            if len(own) and len(own) < len(rows):
                expected[rows] = expected[own[0]]
    old = np.where(present, _values(texts, a, before.unit), a.poses[:, :3])  # filled in: the value the target took
    new = _values(stripped, b, before.unit)
    tol = 0.0005 + 1e-9 * np.abs(old) + 1e-9
    bad = (present | filled) & ~(np.abs(new - old - expected) <= tol)
    if bad.any():
        r, k = map(int, np.argwhere(bad)[0])
        return (f"target at {files[a.file[r]]}:{a.line[r]}: {'XYZ'[k]} {old[r, k]!r} → {new[r, k]!r}, "
                f"expected a change of {expected[r, k]:+.4f}")
    return None


def _values(texts: list[str], t, unit: float = 1.0) -> np.ndarray:
    """The numbers as written at the X/Y/Z spans (NaN where absent), in mm (``unit``: mm per
    unit written, Program.unit)."""
    out = np.full((len(t), 3), np.nan)
    for r, k in zip(*np.nonzero(t.spans[:, :, 0] >= 0)):
        s, e = t.spans[r, k]
        out[r, k] = float(texts[t.file[r]][s:e].replace(" ", "").replace("\t", ""))  # '- 5': KRL allows it
    return out * unit


class Fuzzer:
    """Runs mutants of the corpus in a scratch directory and classifies each outcome."""

    def __init__(self, work: Path, timeout: float = 10.0, offset=OFFSET):
        from ..model.compensator import load_model
        from .models import affine_model

        self.work = work
        # no tool frame in the model card: the corpus programs use several tools (P304 otherwise)
        self.model_path = affine_model(work / "offset.onnx", offset=offset, tool={"name": "any"})
        self.model = load_model(self.model_path)
        self.offset = offset
        self.timeout = timeout
        self.src, self.out, self.cfg = work / "in", work / "out", work / "config"
        self.prior: dict[str, bytes] = {}  # previous output files, which an error must leave alone

    def run(self, sample: Sample, subprocess_run: bool = False, prior: bool = False) -> Outcome:
        files = sample.files
        for folder in (self.src, self.out, self.cfg):
            shutil.rmtree(folder, ignore_errors=True)
            folder.mkdir()
        for name, data in files.items():
            (self.src / name).write_bytes(data)
        for name, data in sample.config.items():
            (self.cfg / name).write_bytes(data)
        main = list(files)[0]
        target = self.out / main
        existing: dict[str, bytes] = {}
        if prior:  # an earlier output in place: an error must leave it byte-identical
            for name in files:
                (self.out / name).write_bytes(b"previous output of " + name.encode() + b"\n")
            existing = {p.name: p.read_bytes() for p in self.out.iterdir()}
        argv = ["compensate", str(self.src / main), "-o", str(target), "--model", str(self.model_path), "-q"]
        for name in sample.config:  # one for now: the CLI takes a single --config
            argv += ["--config", str(self.cfg / name)]
        code, err = (_run_subprocess if subprocess_run else _run_inprocess)(argv, self.timeout)
        if code == "hang":
            return Outcome("hang", f"over {self.timeout} s")
        if isinstance(code, str):
            return Outcome("crash", code)
        if "Traceback" in err or "internal error" in err or " E000 " in err:
            if not subprocess_run:  # again with -v, which re-raises: where it happened
                where = _run_inprocess(argv + ["-v"], self.timeout)[0]
                return Outcome("crash", str(where) if isinstance(where, str) else err.strip()[-400:])
            return Outcome("crash", err.strip()[-400:])
        left = {p.name: p.read_bytes() for p in self.out.iterdir()}
        if code == 2:
            lines = err.strip().splitlines()
            m = MESSAGE.fullmatch(lines[0]) if len(lines) == 1 else None
            if m is None:
                return Outcome("crash", f"exit 2 without one 'path:line:col: CODE message' line: {err[-300:]!r}")
            if left != existing:
                return Outcome("wrong", f"exit 2 but the output directory changed: {sorted(left)}")
            if m.group("code") == P190:
                return Outcome("caught", lines[0])
            return Outcome("error", f"{m.group('code')}")
        if code not in (0, 1):  # (1: written, with targets left as written)
            return Outcome("crash", f"exit {code}: {err[-300:]}")
        if err:
            return Outcome("crash", f"exit {code} with -q but stderr: {err[-300:]!r}")
        if set(left) != set(files):
            return Outcome("wrong", f"output files {sorted(left)}, expected {sorted(files)}")
        names = list(files)
        try:
            problem = self._check(names, files, left, sample)
        except Exception as exc:  # noqa: BLE001 - the checker failing is a finding too, not the end of the run
            problem = f"the output check failed: {type(exc).__name__}: {exc}"
        return Outcome("wrong", problem) if problem else Outcome("output")

    def _check(self, names, files, left, sample) -> str | None:
        return check_output([str(self.src / n) for n in names],
                               [files[n].decode("latin-1") for n in names],
                               [left[n].decode("latin-1") for n in names], self.model, self.offset,
                               [d.decode("latin-1") for d in sample.config.values()] or None)


def fuzz(mutants: int, seed: int = 0, subprocesses: int = 0, timeout: float = 10.0, keep: Path | None = None,
         samples: list[Sample] | None = None) -> tuple[Counter, Counter, list[tuple[str, Outcome]]]:
    """Run ``mutants`` mutants (``subprocesses`` of them through `python -m postproc`).
    Returns the outcome counts, the error codes seen, and the bad outcomes."""
    samples = samples if samples is not None else corpus()
    if not samples:
        raise SystemExit("no samples")
    rng = np.random.default_rng(seed)
    counts: Counter = Counter()
    codes: Counter = Counter()
    bad: list[tuple[str, Outcome]] = []
    every = max(1, mutants // subprocesses) if subprocesses else 0
    with tempfile.TemporaryDirectory(prefix="postproc-fuzz-") as tmp:
        fuzzer = Fuzzer(Path(tmp), timeout)
        for sample in samples:  # the unmutated corpus must compensate cleanly
            outcome = fuzzer.run(sample)
            if outcome.kind != "output":
                bad.append((f"{sample.name} (unmutated)", outcome))
        for i in range(mutants):
            sample = samples[int(rng.integers(len(samples)))]
            mutant = mutate(sample, rng)
            outcome = fuzzer.run(mutant, subprocess_run=bool(every) and i % every == 0, prior=bool(i % 2))
            counts[outcome.kind] += 1
            if outcome.kind == "error":
                codes[outcome.detail] += 1
            elif outcome.kind != "output":
                bad.append((f"mutant {i} of {sample.name}", outcome))
                if keep is not None:
                    folder = keep / f"mutant{i:06d}"
                    folder.mkdir(parents=True, exist_ok=True)
                    for name, data in {**mutant.files, **mutant.config}.items():
                        (folder / name).write_bytes(data)
                    (folder / "outcome.txt").write_text(f"{outcome.kind}: {outcome.detail}\n")
    counts["subprocess"] = len(range(0, mutants, every)) if every else 0
    return counts, codes, bad
