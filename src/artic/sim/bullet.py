"""PyBullet connections without PyBullet's console chatter.

PyBullet's C code prints "pybullet build time: ..." (to stderr) when imported and
"argv[0]=" (to stdout) when a client connects, straight to the file descriptors, which
clutters stage summaries and the JSON that later subcommands print. Both are silenced
here, during the import and the connection only; Python exceptions still propagate.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType
from typing import Any


@contextmanager
def quiet_c_output() -> Iterator[None]:
    """Send file descriptors 1 and 2 to /dev/null for the duration (C-level prints too)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 1)
            os.dup2(null.fileno(), 2)
        yield
    finally:
        for fd, copy in zip((1, 2), saved, strict=True):
            os.dup2(copy, fd)
            os.close(copy)


def pybullet_module() -> ModuleType:
    """`import pybullet`, quietly."""
    with quiet_c_output():
        import pybullet

    return pybullet


def connect_direct() -> Any:
    """A `BulletClient` in DIRECT mode (no GUI, one per process or backend)."""
    pybullet = pybullet_module()
    from pybullet_utils.bullet_client import BulletClient

    with quiet_c_output():
        return BulletClient(connection_mode=pybullet.DIRECT)
