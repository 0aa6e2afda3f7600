"""Speed of the KRL reader on a generated CAM program (default 1,000,000 LIN lines).

    python benchmarks/krl_read_speed.py [--lines N] [--crlf] [--named N] [--in-for]

Prints lines/s of ``postproc.programs.krl.read``, its peak memory (tracemalloc, measured in
a second run because tracing slows Python down) and, for comparison, the time of a plain
regex pass that rewrites the X/Y/Z numbers of the same text.
"""
from __future__ import annotations

import argparse
import re
import time
import tracemalloc

import numpy as np


def cam_program(lines: int, crlf: bool, seed: int = 0) -> str:
    """A CAM-style module: header, $BASE/$TOOL, then ``lines`` LIN lines (1 in 50 with
    only X/Y/Z, 1 in 1000 a $VEL.CP setting)."""
    rng = np.random.default_rng(seed)
    xyz = rng.uniform([-200, -300, 0], [200, 300, 400], size=(lines, 3))
    abc = rng.uniform(-5, 5, size=(lines, 3)) + [0, 90, 0]
    out = ["&ACCESS RVP", "&REL 1", "DEF cam_big( )", "$BASE = {X 2000.0,Y 0.0,Z 600.0,A 0.0,B 0.0,C 0.0}",
           "$TOOL = {X 0.0,Y 0.0,Z 150.0,A 0.0,B 0.0,C 0.0}", "$VEL.CP = 0.2", "$APO.CVEL = 90"]
    for i in range(lines):
        x, y, z = xyz[i]
        a, b, c = abc[i]
        if i % 1000 == 999:
            out.append("$VEL.CP = 0.25")
        if i % 50 == 7:
            out.append(f"LIN {{X {x:.3f},Y {y:.3f},Z {z:.3f}}} C_VEL")
        else:
            out.append(f"LIN {{X {x:.3f},Y {y:.3f},Z {z:.3f},A {a:.3f},B {b:.3f},C {c:.3f}}} C_VEL")
    out.append("END")
    nl = "\r\n" if crlf else "\n"
    return nl.join(out) + nl


def named_program(points: int) -> tuple[str, str]:
    """A teach-pendant style module: ``LIN XPi C_DIS`` in the .src, ``DECL E6POS XPi={…}``
    in the .dat (every line a different name: the shape cache must abstract the digits)."""
    rng = np.random.default_rng(1)
    xyz = rng.uniform([-200, -300, 0], [200, 300, 400], size=(points, 3))
    src = ["DEF named( )", "$BASE = {X 2000.0,Y 0.0,Z 600.0,A 0.0,B 0.0,C 0.0}"]
    src += [f"LIN XP{i + 1} C_DIS" for i in range(points)] + ["END"]
    dat = ["DEFDAT named"] + [
        f"DECL E6POS XP{i + 1}={{X {x:.3f},Y {y:.3f},Z {z:.3f},A 0.0,B 90.0,C 0.0,S 6,T 18,E1 0.0,E2 0.0}}"
        for i, (x, y, z) in enumerate(xyz)] + ["ENDDAT"]
    return "\n".join(src) + "\n", "\n".join(dat) + "\n"


PLAIN = re.compile(r"(\{X )(-?[\d.]+)(,Y )(-?[\d.]+)(,Z )(-?[\d.]+)")


def plain_pass(text: str) -> str:
    """What a minimal rewrite does: find each X/Y/Z triple and write numbers back."""
    return PLAIN.sub(lambda m: f"{m[1]}{float(m[2]):.3f}{m[3]}{float(m[4]):.3f}{m[5]}{float(m[6]):.3f}", text)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--lines", type=int, default=1_000_000)
    ap.add_argument("--crlf", action="store_true")
    ap.add_argument("--no-memory", action="store_true", help="skip the (slow) tracemalloc run")
    ap.add_argument("--in-for", action="store_true",
                    help="also time the same program with its motions inside a FOR loop (the reader runs the "
                    "body's frame statements once more to learn what an iteration changes)")
    ap.add_argument("--named", type=int, default=0, metavar="N",
                    help="also time a teach-pendant style module of N named points (.src + .dat)")
    args = ap.parse_args()
    t0 = time.perf_counter()
    from postproc.programs import krl

    krl.parser()
    print(f"import + parser: {time.perf_counter() - t0:.3f} s")
    text = cam_program(args.lines, args.crlf)
    nlines = text.count("\n")
    print(f"program: {nlines:,} lines, {len(text) / 1e6:.1f} MB")
    t0 = time.perf_counter()
    prog = krl.read(["cam_big.src"], [text])
    dt = time.perf_counter() - t0
    print(f"krl.read: {dt:.2f} s = {nlines / dt:,.0f} lines/s, {len(prog.targets):,} targets "
          f"({len(prog.targets) / dt:,.0f} targets/s)")
    t0 = time.perf_counter()
    plain_pass(text)
    dp = time.perf_counter() - t0
    print(f"plain regex rewrite pass: {dp:.2f} s (read / plain = {dt / dp:.2f})")
    if args.in_for:
        looped = text.replace("$APO.CVEL = 90", "$APO.CVEL = 90\nFOR i = 1 TO 3", 1).replace("\nEND", "\nENDFOR\nEND")
        t0 = time.perf_counter()
        krl.read(["cam_big.src"], [looped])
        dl = time.perf_counter() - t0
        print(f"the same inside FOR … ENDFOR: {dl:.2f} s (in a loop / plain = {dl / dt:.2f})")
    if args.named:
        src, dat = named_program(args.named)
        t0 = time.perf_counter()
        prog = krl.read(["named.src", "named.dat"], [src, dat])
        dt = time.perf_counter() - t0
        n = src.count("\n") + dat.count("\n")
        print(f"named points: {len(prog.targets):,} targets, {n:,} lines in {dt:.2f} s = {n / dt:,.0f} lines/s")
    if not args.no_memory:
        del prog
        tracemalloc.start()
        krl.read(["cam_big.src"], [text])
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        print(f"peak memory of read (tracemalloc, beyond the {len(text) / 1e6:.0f} MB text): {peak / 1e6:.0f} MB")
    import resource

    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux
    print(f"peak resident memory of this whole process (text, copies, numpy): {rss:.0f} MB")


if __name__ == "__main__":
    main()
