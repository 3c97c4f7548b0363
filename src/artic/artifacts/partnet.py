"""Read a PartNet-Mobility model folder (the data of thesis section 4.5).

A folder holds `mobility.urdf`, the OBJ meshes its visuals reference (usually
`textured_objs/*.obj`, several per link) and optionally `semantics.txt`. This module
reads the files; the conversion is `artic.objects.partnet.partnet_object` (pure).
Every problem is an InputError naming the file.
"""

from __future__ import annotations

from pathlib import Path

from artic.errors import InputError
from artic.objects.partnet import (
    PartNetObject,
    mesh_filenames,
    parse_obj,
    parse_semantics,
    partnet_object,
)

URDF = "mobility.urdf"
SEMANTICS = "semantics.txt"


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(f"{path}: cannot read ({type(err).__name__})") from None


def load_partnet(folder: Path, merge_fixed: bool = False, density: float = 500.0) -> PartNetObject:
    """The PartNet-Mobility model in `folder`: ArticulatedObject + tree ground truth.

    merge_fixed: merge links on fixed joints into their parents (see
    `artic.objects.partnet`). density: kg/m^3 for links without a URDF inertial.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: not a folder; expected a PartNet-Mobility model folder")
    urdf_path = folder / URDF
    if not urdf_path.is_file():
        raise InputError(f"{urdf_path}: missing; a PartNet-Mobility folder holds {URDF}")
    text = _read_text(urdf_path)
    meshes = {}
    for name in mesh_filenames(text, source=str(urdf_path)):
        path = folder / name
        if not path.is_file():
            raise InputError(f"{path}: mesh file referenced by {urdf_path} is missing")
        try:
            data = path.read_bytes()
        except OSError as err:
            raise InputError(f"{path}: cannot read ({type(err).__name__})") from None
        meshes[name] = parse_obj(data, source=str(path))
    semantics_path = folder / SEMANTICS
    semantics = None
    if semantics_path.is_file():
        semantics = parse_semantics(_read_text(semantics_path), source=str(semantics_path))
    return partnet_object(
        text,
        meshes,
        semantics,
        source=str(urdf_path),
        semantics_source=str(semantics_path),
        merge_fixed=merge_fixed,
        density=density,
    )
