"""`write_urdf_folder`: an object's URDF and meshes written into a folder, for the tests
that load objects into PyBullet (tests/objects)."""

from __future__ import annotations

from pathlib import Path

from artic.objects.model import ArticulatedObject
from artic.objects.urdf import write_urdf


def write_urdf_folder(obj: ArticulatedObject, folder: Path) -> Path:
    """`obj`'s `<name>.urdf` and its meshes in `folder`; returns the URDF's path."""
    files = write_urdf(obj)
    path = folder / f"{obj.name}.urdf"
    path.write_text(files.urdf)
    for relative, text in files.meshes.items():
        (folder / relative).parent.mkdir(parents=True, exist_ok=True)
        (folder / relative).write_text(text)
    return path
