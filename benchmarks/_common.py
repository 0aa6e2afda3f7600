"""What the benchmarks share: running the CLI as a user would, the machine's load, and a KRL program of poses."""
from __future__ import annotations

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


def krl_program(name: str, poses: np.ndarray) -> str:
    """A module ``name`` that moves LIN through ``poses`` [N, 6] (robot base, 4 decimals)."""
    lines = [f"DEF {name}( )"] + ["  LIN {" + ",".join(f"{k} {v:.4f}" for k, v in zip("XYZABC", p)) + "}"
                                  for p in poses]
    return "\n".join(lines + ["END", ""])
