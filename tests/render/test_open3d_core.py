"""`open3d_core()`: Open3D's compiled bindings without Open3D-ML and the visualization
package, the same classes a later `import open3d` gives, and the only way artic's
refinement, renderer and baselines reach Open3D. Checks run in a fresh interpreter
(`sys.modules` of this one holds whatever other tests imported)."""

from __future__ import annotations

import re
from pathlib import Path

from fresh_python import in_fresh_python, loaded_code

#: what `import open3d` brings beside the bindings, which artic never uses
EXTRAS = ("open3d.ml", "open3d.visualization", "sklearn")
LOADED = loaded_code(EXTRAS)


def test_the_bindings_load_without_the_packages_extras_and_are_open3ds_own() -> None:
    code = (
        "import json, sys\n"
        "from artic.render.open3d_core import open3d_core\n"
        "o3d = open3d_core()\n"
        "scene = o3d.t.geometry.RaycastingScene()\n" + LOADED + "before = loaded\n"
        "import open3d\n"
        "same = open3d.t.geometry.RaycastingScene is o3d.t.geometry.RaycastingScene\n"
        "print(json.dumps([before, same, open3d_core() is o3d]))"
    )
    assert in_fresh_python(code) == [[], True, True]


def test_after_import_open3d_the_packages_bindings_are_used() -> None:
    code = (
        "import json, open3d\n"
        "from artic.render.open3d_core import open3d_core\n"
        "print(json.dumps(open3d_core() is open3d.pybind))"
    )
    assert in_fresh_python(code) is True


def test_rendering_and_the_refinements_plane_fit_load_only_the_bindings() -> None:
    # a rendered microwave's door cloud through RANSAC: the two uses of `artic predict`
    code = (
        "import json, sys\n"
        "import numpy as np\n"
        "from artic.geometry.camera import CameraIntrinsics\n"
        "from artic.kinematics.refine import Hypothesis, _ransac\n"
        "from artic.objects.categories import build\n"
        "from artic.objects.spec import PartsConfig\n"
        "from artic.render.raycast import RaycastBackend\n"
        "camera = CameraIntrinsics(fx=105.4, fy=105.4, cx=95.5, cy=53.5, width=192, height=108)\n"
        "h = Hypothesis(1.4, 0.05, -0.45, 0.3, 0.4, 0.6, 0.35, 1, (0.5,))\n"
        "obj = build(h.spec('microwave', PartsConfig()))\n"
        "points = camera.back_project(RaycastBackend(camera).render(obj, np.array(h.qs)).depth)\n"
        "inliers = int(_ransac(points, seed=0).sum())\n" + LOADED +
        "print(json.dumps([loaded, len(points) > 0 and inliers > 0]))"
    )  # fmt: skip
    assert in_fresh_python(code) == [[], True]


#: an import of the package itself: `import open3d`, `from open3d import ...`
STATEMENT = re.compile(r"^\s*(import open3d\b|from open3d\b)", re.MULTILINE)


def test_the_module_is_the_only_door_to_open3d() -> None:
    assert STATEMENT.search("x = 1\n    import open3d as o3d\n")
    src = Path(__file__).parents[2] / "src" / "artic"
    direct = [
        str(p.relative_to(src))
        for p in src.rglob("*.py")
        if STATEMENT.search(p.read_text()) and p.name != "open3d_core.py"
    ]
    assert direct == []
