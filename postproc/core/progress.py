"""Progress on stderr for the long commands (compensate, train, plan, measure, fleet): a tqdm
bar when asked for, nothing otherwise (the CLI asks only on a terminal and without -q).

Named stages (:func:`stages`) are passed their switch by the caller; a count of work done
(:class:`ProgressBar`: targets, bytes, robots) reads it from :func:`reporting`, which the CLI
opens around a command, so library code deep down reports without an argument threaded
through every signature (as ``logging`` does). A ProgressBar shows once the work has
taken DELAY_S seconds: short runs print nothing."""
from __future__ import annotations

from contextlib import contextmanager
from contextvars import ContextVar
from typing import Callable, Iterator

DELAY_S = 2.0
REFRESH_S = 0.1  # (tqdm's mininterval: the bar redrawn at most this often)

_ON: ContextVar[bool] = ContextVar("postproc_progress", default=False)


@contextmanager
def reporting(enabled: bool) -> Iterator[None]:
    """ProgressBars made inside show bars (``enabled``) or nothing."""
    token = _ON.set(bool(enabled))
    try:
        yield
    finally:
        _ON.reset(token)


class ProgressBar:
    """A bar over ``total`` units of work (``unit``: "target", "B", "robot"), updated with
    :meth:`update` (from any thread); a no-op outside ``reporting(True)`` (tqdm not imported)."""

    def __init__(self, desc: str, total: int, unit: str = "it", scale: bool = False):
        self._bar = None
        if _ON.get() and total > 0:
            from tqdm import tqdm

            self._bar = tqdm(total=total, desc=desc, unit=unit, unit_scale=scale, leave=False,
                             dynamic_ncols=True, delay=DELAY_S, mininterval=REFRESH_S, miniters=1)

    def update(self, n: int) -> None:
        if self._bar is not None:
            self._bar.update(n)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> "ProgressBar":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@contextmanager
def stages(names: list[str], desc: str, enabled: bool) -> Iterator[Callable[[str], None]]:
    """A bar over named stages: call the yielded ``start(name)`` as each begins (the bar shows
    it and counts the one before as done). Disabled: a no-op, and tqdm is not even imported."""
    if not enabled:
        yield lambda name: None
        return
    from tqdm import tqdm

    bar = tqdm(total=len(names), desc=desc, leave=False, dynamic_ncols=True,
               bar_format="{desc} {bar} {n_fmt}/{total_fmt}{postfix} [{elapsed}]")
    started = 0

    def start(name: str) -> None:
        nonlocal started
        if started:
            bar.update(1)
        started += 1
        bar.set_postfix_str(name)

    try:
        yield start
        bar.update(bar.total - bar.n)
    finally:
        bar.close()
