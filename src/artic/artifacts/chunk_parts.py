"""The parts stages' chunks leave in the work area for finalize to merge: read once,
in the order given, and deleted as they are read (finalize's merged file replaces them)."""

from __future__ import annotations

import csv
import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any


def take_csv_rows(paths: Iterable[Path]) -> list[list[str]]:
    """The data rows (header left out) of CSV files, in order; each file is deleted."""
    rows: list[list[str]] = []
    for path in paths:
        with path.open(newline="") as f:
            rows.extend(list(csv.reader(f))[1:])
        path.unlink()
    return rows


def take_json(paths: Iterable[Path]) -> list[Any]:
    """The values of JSON files, in order; each file is deleted."""
    values = []
    for path in paths:
        values.append(json.loads(path.read_text()))
        path.unlink()
    return values
