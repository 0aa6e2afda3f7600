"""Progress on stderr for the long commands (train, plan, measure): a tqdm bar when asked
for, nothing otherwise (the CLI asks only on a terminal and without -q)."""
from __future__ import annotations

from contextlib import contextmanager
from typing import Callable, Iterator


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
