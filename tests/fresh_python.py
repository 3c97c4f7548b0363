"""Checks run by a fresh interpreter, for tests of what a command imports (`sys.modules`
of the test process holds whatever other tests imported)."""

from __future__ import annotations

import json
import subprocess
import sys


def in_fresh_python(code: str, env: dict[str, str] | None = None) -> object:
    """The JSON the last line of `code`'s output holds, run by a fresh interpreter."""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def loaded_code(names: tuple[str, ...]) -> str:
    """Python source setting `loaded`: which of `names` (modules or packages) are loaded."""
    return (
        f"loaded = [n for n in {list(names)!r} "
        "if any(m == n or m.startswith(n + '.') for m in sys.modules)]\n"
    )


def loaded_after(statement: str, names: tuple[str, ...]) -> list[str]:
    """Which of `names` (modules or packages) are loaded after `statement`."""
    code = f"import json, sys\n{statement}\n{loaded_code(names)}print(json.dumps(loaded))"
    return list(in_fresh_python(code))  # type: ignore[call-overload]
