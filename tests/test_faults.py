"""Atomic writes under faults: a .src and its .dat are replaced together or not at all.

* Every OS call of the write that can fail (creating, writing, syncing, linking, renaming)
  fails in turn, with an OSError or a Ctrl-C: the CLI exits 2 with a message, the previous
  output files are byte-identical and nothing else is left in the directory.
* A real `postproc compensate` process is SIGKILLed at random moments of its write phase,
  and once exactly between the renames of the .src and the .dat: the output names only ever
  hold a complete old or complete new file; the pair is the old or the new pair, or — killed
  between the two renames — a journal says so and the next write (``recover``) completes
  it; leftovers are hidden ``.<name>.*`` files only, never an output name.
"""
import os
import re
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np
import pytest

from postproc.cli import main
from postproc.core.atomic import recover

from helpers import REPO

SRC = "&ACCESS RVP\r\nDEF cell( )\r\n$BASE = {X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}\r\n{body}END\r\n"
DAT = "DEFDAT cell\r\n{decls}ENDDAT\r\n"


def module(n_inline: int, n_vars: int, seed: int = 0) -> tuple[str, str]:
    rng = np.random.default_rng(seed)
    xyz = np.round(rng.uniform([1800, -400, 700], [2200, 400, 1100], (n_inline + n_vars, 3)), 3)
    body = "".join(f"LIN {{X {x:.3f},Y {y:.3f},Z {z:.3f},A 0.0,B 90.0,C 0.0}} C_DIS\r\n" for x, y, z in xyz[:n_inline])
    body += "".join(f"LIN XP{i}\r\n" for i in range(n_vars))
    decls = "".join(f"DECL E6POS XP{i}={{X {x:.3f},Y {y:.3f},Z {z:.3f},A 0.0,B 90.0,C 0.0}}\r\n"
                    for i, (x, y, z) in enumerate(xyz[n_inline:]))
    return SRC.replace("{body}", body), DAT.replace("{decls}", decls)


@pytest.fixture
def cell(tmp_path, affine):
    """A module, a model, and an output directory that holds a previous output pair."""
    src, dat = module(40, 10)
    (tmp_path / "cell.src").write_text(src, newline="")
    (tmp_path / "cell.dat").write_text(dat, newline="")
    out = tmp_path / "out"
    out.mkdir()
    old = {"cell.src": b"previous cell.src\r\n", "cell.dat": b"previous cell.dat\r\n"}
    for name, data in old.items():
        (out / name).write_bytes(data)
    model = affine(offset=(0.1, 0.2, -0.1), tool={"name": "any"})
    argv = ["compensate", str(tmp_path / "cell.src"), "-o", str(out / "cell.src"), "--base", "0", "--tool", "model",
            "--model", str(model)]  # (made-up programs that set no $BASE/$TOOL: stated, as a user would)
    from postproc.programs.krl import parser

    parser()  # built (and its lark cache written) before any OS call is made to fail
    from postproc.model.compensator import load_model

    load_model(model)  # the model's session cache written (postproc.model.session) before any OS call is made to fail
    return argv, out, old


def listing(folder):
    return {p.name: p.read_bytes() for p in folder.iterdir()}


class Fault:
    """Make the ``nth`` call of ``name`` (an attribute of module ``where``) raise ``error``."""

    def __init__(self, monkeypatch, where, name, nth, error):
        self.calls = 0
        real = getattr(where, name)

        def patched(*args, **kwargs):
            self.calls += 1
            if self.calls == nth:
                raise error
            return real(*args, **kwargs)

        monkeypatch.setattr(where, name, patched)


class FailingFile:
    """A file object whose write fails (a full disk), for os.fdopen."""

    def __init__(self, fh, error):
        self.fh, self.error = fh, error

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.fh.close()

    def write(self, data):
        self.fh.write(data[: len(data) // 2])  # half of it reached the disk
        raise self.error

    def __getattr__(self, name):
        return getattr(self.fh, name)


CALLS = [("tempfile", "mkstemp", 2), ("os", "fsync", 2), ("os", "chmod", 2), ("os", "link", 2), ("os", "replace", 2),
         ("os", "fdopen", 2)]


@pytest.mark.parametrize("module_name, name, calls", CALLS)
@pytest.mark.parametrize("error", ["disk full", "ctrl-c"])
def test_a_failing_write_leaves_the_previous_outputs(cell, monkeypatch, capsys, module_name, name, calls, error):
    argv, out, old = cell
    where = {"os": os, "tempfile": tempfile}[module_name]
    for nth in range(1, calls + 1):  # the .src's call, then the .dat's
        exc = OSError(28, "No space left on device") if error == "disk full" else KeyboardInterrupt()
        with monkeypatch.context() as m:
            if name == "fdopen":
                real = os.fdopen
                count = {"n": 0}

                def fdopen(fd, *args, **kwargs):
                    count["n"] += 1
                    fh = real(fd, *args, **kwargs)
                    return FailingFile(fh, exc) if count["n"] == nth else fh

                m.setattr(os, "fdopen", fdopen)
            else:
                Fault(m, where, name, nth, exc)
            code = main(argv)
        err = capsys.readouterr().err
        assert code == (2 if error == "disk full" else 130), err
        expected = "P110 cannot write: No space left on device" if error == "disk full" else "postproc: interrupted"
        assert expected in err
        assert listing(out) == old, (name, nth)  # the previous pair, nothing else (no temp, no backup)


def test_without_previous_outputs_a_failing_write_leaves_nothing(cell, monkeypatch, capsys):
    argv, out, old = cell
    for name in old:
        (out / name).unlink()
    with monkeypatch.context() as m:
        Fault(m, os, "replace", 2, OSError(5, "Input/output error"))
        assert main(argv) == 2
    assert "P110 cannot write: Input/output error" in capsys.readouterr().err
    assert listing(out) == {}


def test_the_write_itself_is_complete_and_keeps_permissions(cell, capsys):
    argv, out, old = cell
    os.chmod(out / "cell.src", 0o640)
    assert main(argv + ["-q"]) == 0
    new = listing(out)
    assert set(new) == {"cell.src", "cell.dat"}
    assert new["cell.src"].endswith(b"END\r\n") and new["cell.dat"].endswith(b"ENDDAT\r\n")
    assert (out / "cell.src").stat().st_mode & 0o777 == 0o640


# --------------------------------------------------------------------------- SIGKILL


HIDDEN = re.compile(r"\.cell\.(src|dat)\.(.+\.tmp|\d+\.bak)|\.cell\.src\.postproc-journal")


@pytest.mark.slow
def test_sigkill_during_the_write_never_leaves_a_mix_or_a_truncated_file(tmp_path, affine):
    src, dat = module(15_000, 4_000)  # ~1.2 MB .src, ~0.3 MB .dat: the write takes a while
    (tmp_path / "cell.src").write_text(src, newline="")
    (tmp_path / "cell.dat").write_text(dat, newline="")
    out = tmp_path / "out"
    out.mkdir()
    model = affine(offset=(0.1, 0.2, -0.1), tool={"name": "any"})
    cmd = [sys.executable, "-m", "postproc", "compensate", str(tmp_path / "cell.src"), "-o", str(out / "cell.src"),
           "--base", "0", "--tool", "model", "--model", str(model), "-q"]
    # the old pair: this program compensated with another model; the new pair: a clean run
    other = affine(offset=(-0.1, 0.0, 0.1), tool={"name": "any"})
    assert main(cmd[3:-3] + ["--model", str(other), "-q"]) == 0
    old = listing(out)
    assert main(cmd[3:]) == 0
    new = listing(out)
    assert old.keys() == new.keys() == {"cell.src", "cell.dat"} and old != new
    rng = np.random.default_rng(7)
    outcomes = []
    for _ in range(5):
        for name, data in old.items():
            (out / name).write_bytes(data)
        proc = subprocess.Popen(cmd, cwd=REPO, stderr=subprocess.DEVNULL)
        # wait for the write phase (a temp file appears), then kill within its first ~20 ms
        deadline = time.monotonic() + 60
        while proc.poll() is None and time.monotonic() < deadline:
            if any(p.name.endswith(".tmp") for p in out.iterdir()):
                break
            time.sleep(0.001)
        time.sleep(float(rng.uniform(0, 0.02)))
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        files = {p.name: p.read_bytes() for p in out.iterdir()}
        extra = {n for n in files if n not in ("cell.src", "cell.dat")}
        assert all(HIDDEN.fullmatch(n) for n in extra), extra  # leftovers: hidden, never an output name
        for name in ("cell.src", "cell.dat"):
            assert files[name] in (old[name], new[name]), f"{name}: {len(files[name])} bytes"  # never truncated
        if ".cell.src.postproc-journal" not in files:
            assert files["cell.src"] == old["cell.src"] and files["cell.dat"] == old["cell.dat"] or \
                files["cell.src"] == new["cell.src"] and files["cell.dat"] == new["cell.dat"]
        recover(out / "cell.src")  # what the next write runs first
        pair = (out / "cell.src").read_bytes(), (out / "cell.dat").read_bytes()
        assert pair in ((old["cell.src"], old["cell.dat"]), (new["cell.src"], new["cell.dat"]))
        outcomes.append("new" if pair[0] == new["cell.src"] else "old")
        for n in extra:
            (out / n).unlink(missing_ok=True)
    # (which of the two each kill left depends on timing; both are correct)
    assert len(outcomes) == 5


KILL_BETWEEN_RENAMES = """
import os, signal, sys
real = os.replace
def replace(src, dst):
    real(src, dst)
    if os.path.basename(dst) == "cell.src":  # the .src is renamed, the .dat is not yet
        os.kill(os.getpid(), signal.SIGKILL)
os.replace = replace
from postproc.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_sigkill_between_the_two_renames_is_completed_by_the_next_write(cell, affine):
    argv, out, old = cell
    killed = argv[:-1] + [str(affine(offset=(-0.2, 0.1, 0.0), tool={"name": "any"}))]
    proc = subprocess.run([sys.executable, "-c", KILL_BETWEEN_RENAMES, *killed, "-q"], cwd=REPO)
    assert proc.returncode == -signal.SIGKILL
    # the worst moment: the killed run's .src beside the old .dat, and the journal that says so
    files = listing(out)
    assert files["cell.dat"] == old["cell.dat"] and files["cell.src"] != old["cell.src"]
    assert len(files[".cell.src.postproc-journal"].decode().splitlines()) == 2
    # recover completes the killed run's pair (once; a second call finds nothing to do)
    assert recover(out / "cell.src") and not recover(out / "cell.src")
    killed_pair = listing(out)
    assert set(killed_pair) == {"cell.src", "cell.dat"} and killed_pair["cell.src"] == files["cell.src"]
    assert killed_pair["cell.dat"] != old["cell.dat"]
    # and the next write runs it first by itself
    for name, data in old.items():
        (out / name).write_bytes(data)
    subprocess.run([sys.executable, "-c", KILL_BETWEEN_RENAMES, *killed, "-q"], cwd=REPO)
    assert main(argv + ["-q"]) == 0
    files = listing(out)
    assert set(files) == {"cell.src", "cell.dat"}  # journal, temps and backups gone
    assert files["cell.src"] != killed_pair["cell.src"] and files["cell.dat"] != killed_pair["cell.dat"]
