"""Build hook: copy the top-level `conf/`, `stages/` and `models/` into the package at
build time.

The repository keeps `conf/`, `stages/` and the shipped model store `models/` at its top
level (the project's layout); a wheel carries them as `artic/conf/`, `artic/stages/` and
`artic/models/`, where `artic.config.compose` finds them with `importlib.resources`. An
editable install reads the top-level folders directly, so nothing is copied then.
Everything else is in pyproject.toml.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent
DATA = ("conf", "stages", "models")


class BuildPyWithData(build_py):
    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):
            return
        for name in DATA:
            source = HERE / name
            if not source.is_dir():
                raise SystemExit(f"setup.py: {source} is missing; cannot build artic")
            target = Path(self.build_lib) / "artic" / name
            if target.exists():
                shutil.rmtree(target)
            shutil.copytree(source, target, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))


setup(cmdclass={"build_py": BuildPyWithData})
