"""Wall-clock times of a stage's work, kept apart from its data.

Times vary from run to run; the data files stay byte-for-byte reproducible because the
times live only in `timings.csv` / `timings.json` (`manifest.TIMING_FILES`, left out of
the content hash). The training stages write one `timings.csv` row per epoch.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from artic.artifacts.formats import write_csv

TIMINGS_CSV = "timings.csv"
SECONDS = "seconds"


def write_epoch_timings(folder: Path, phases: Mapping[str, Sequence[Mapping[str, Any]]]) -> None:
    """`timings.csv` (phase, epoch, seconds): one row per epoch of each phase's history."""
    rows = [[phase, h["epoch"], h[SECONDS]] for phase, hist in phases.items() for h in hist]
    write_csv(folder / TIMINGS_CSV, ["phase", "epoch", SECONDS], rows)


def write_history(
    path: Path, history: Sequence[Mapping[str, Any]], columns: Sequence[str] | None = None
) -> None:
    """A per-epoch history as CSV (metrics.csv): `columns` of each epoch, by default every
    column but the wall-clock `seconds` (those go to `write_epoch_timings`)."""
    if columns is None:
        columns = [c for c in (history[0] if history else ["epoch"]) if c != SECONDS]
    write_csv(path, columns, [[h[c] for c in columns] for h in history])
