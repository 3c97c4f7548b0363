"""Progress for long work: a Rich bar on a terminal, plain log lines otherwise (the stage
runner's chunks; nothing of artic imported, so any package can report through it)."""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

log = logging.getLogger("artic")


@contextmanager
def progress(description: str, total: int, unit: str) -> Iterator[Callable[[int], None]]:
    """Yield `advance(n)`. Rich bar (rate, ETA) when stderr is a terminal; otherwise a
    log line at most every 10 s and at the end."""
    if sys.stderr.isatty():
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        columns = (
            TextColumn("[bold]{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("[cyan]{task.fields[rate]}"),
            TimeElapsedColumn(),
            TextColumn("ETA"),
            TimeRemainingColumn(),
        )
        start = time.perf_counter()
        with Progress(*columns, console=Console(stderr=True), transient=False) as bar:
            task = bar.add_task(description, total=total, rate="")

            def advance_rich(n: int) -> None:
                bar.advance(task, n)
                done = bar.tasks[0].completed
                rate = done / max(time.perf_counter() - start, 1e-9)
                bar.update(task, rate=f"{rate:,.0f} {unit}/s")

            yield advance_rich
        return

    state = {"done": 0, "last": time.perf_counter()}
    start = time.perf_counter()

    def advance_plain(n: int) -> None:
        state["done"] += n
        now = time.perf_counter()
        if now - state["last"] >= 10.0 or state["done"] >= total:
            state["last"] = now
            rate = state["done"] / max(now - start, 1e-9)
            eta = (total - state["done"]) / rate if rate > 0 else float("inf")
            log.info(
                "%s: %d/%d %s (%.3g %s/s, ETA %.0f s)",
                description,
                state["done"],
                total,
                unit,
                rate,
                unit,
                eta,
            )

    yield advance_plain
