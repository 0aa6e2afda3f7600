"""What the benchmarks share: running the CLI as a user would, the machine's load, and a KRL program of poses."""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def cli(*args: str, nice: bool = False, env: dict | None = None) -> tuple[str, float]:
    """Run `python -m postproc ARGS` from the repository (niced if asked): (stdout, wall s).
    Exit 0 and 1 (findings, a gate) are results; anything else stops the benchmark."""
    t0 = time.perf_counter()
    command = (["nice", "-n", "5"] if nice else []) + [sys.executable, "-m", "postproc", *args]
    run = subprocess.run(command, cwd=ROOT, text=True, capture_output=True, env=env)
    if run.returncode not in (0, 1):
        raise SystemExit(f"postproc {' '.join(args)} failed ({run.returncode}):\n{run.stderr}")
    return run.stdout, time.perf_counter() - t0


def load() -> str:
    """The machine's load averages, as `uptime` prints them (the machine is shared)."""
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.split("load average:")[-1].strip()


def krl_program(name: str, poses: np.ndarray, tool=(300.0, 0.0, 75.0, 0.0, 0.0, 0.0)) -> str:
    """A module ``name`` that moves LIN through ``poses`` [N, 6] (robot base, 4 decimals) with
    ``tool`` (default: the simulated KR500's spindle, ``models/kr500.toml``) as $TOOL: it sets
    its frames, as a program must (else its targets are left as written, P220/P221)."""
    frame = ",".join(f"{k} {v:g}" for k, v in zip("XYZABC", tool))
    lines = [f"DEF {name}( )", "  $BASE = {X 0,Y 0,Z 0,A 0,B 0,C 0}", f"  $TOOL = {{{frame}}}"]
    lines += ["  LIN {" + ",".join(f"{k} {v:.4f}" for k, v in zip("XYZABC", p)) + "}" for p in poses]
    return "\n".join(lines + ["END", ""])


RESULTS = Path(__file__).resolve().parent / "results"


def record(name: str, figures: dict, argv: list[str] | None = None) -> Path:
    """Write a benchmark's figures to ``benchmarks/results/NAME.json`` (with the command and
    the machine's load): the README's figures are taken from there (``benchmarks/figures.py``),
    never copied by hand."""
    import json
    import platform
    from datetime import datetime, timezone

    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / f"{name}.json"
    command = "python benchmarks/" + " ".join([Path(sys.argv[0]).name] + list(sys.argv[1:] if argv is None else argv))
    entry = {"command": command, "when": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%MZ"), "load": load(),
             "cores": os.cpu_count(), "python": platform.python_version(), "figures": figures}
    path.write_text(json.dumps(entry, indent=1, sort_keys=False) + "\n")
    return path
