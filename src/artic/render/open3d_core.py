"""Open3D's compiled bindings, without the rest of its Python package.

`import open3d` runs the package's `__init__`, which after loading the compiled bindings
(`open3d.cpu.pybind`: geometry, pipelines, the tensor API with `RaycastingScene`) imports
Open3D-ML (scikit-learn and its datasets) and the visualization package. artic uses
neither, and they are most of the import: on an idle 2-core machine importing Open3D
took about 2.1 s, of which Open3D-ML 1.1 s and the visualization 0.5 s. Every artic
module that needs Open3D takes it from `open3d_core()`, so `artic predict`'s refinement
(ray casting, RANSAC) loads only the bindings (docs/benchmarks.md has the wall times).

The bindings are the same module `import open3d` loads (`open3d.pybind`; its names are
`open3d`'s: `core`, `geometry`, `pipelines`, `t`, `utility`) and are registered under
the same name, so a later `import open3d` in the process finds them and shares their
classes. Open3D's own choice of device is kept: a wheel built with CUDA whose CUDA
bindings find a device gets `import open3d` itself (which then loads the CUDA bindings);
so does an Open3D whose layout is not the one read here, or one already imported.
"""

from __future__ import annotations

import functools
import importlib
import importlib.machinery
import importlib.util
import os
import sys
from ctypes import CDLL
from pathlib import Path
from types import ModuleType

CPU_BINDINGS = "open3d.cpu.pybind"
#: the library every CUDA program needs to find a device
NVIDIA_DRIVER = "libcuda.so.1"


@functools.cache
def open3d_core() -> ModuleType:
    """Open3D's compiled bindings (module docstring): `open3d_core().t.geometry
    .RaycastingScene`, `open3d_core().geometry.PointCloud`, ... as on `open3d`."""
    spec = importlib.util.find_spec("open3d")
    if "open3d" in sys.modules or spec is None or not spec.origin:
        return _package()
    root = Path(spec.origin).parent
    cpu = _bindings(root / "cpu")
    if cpu is None or _cuda_device(root, cpu):
        return _package()
    # what open3d/__init__.py sets before loading its bindings
    os.environ["KMP_DUPLICATE_LIB_OK"] = "True"
    os.environ["TCM_ENABLE"] = "1"
    loader = importlib.machinery.ExtensionFileLoader(CPU_BINDINGS, str(cpu))
    bindings_spec = importlib.util.spec_from_loader(CPU_BINDINGS, loader)
    assert bindings_spec is not None
    module = importlib.util.module_from_spec(bindings_spec)
    loader.exec_module(module)
    sys.modules[CPU_BINDINGS] = module
    return module


def _package() -> ModuleType:
    """The bindings as `import open3d` chose them (CPU or CUDA)."""
    package = importlib.import_module("open3d")
    bindings: ModuleType = package.pybind
    return bindings


def _bindings(folder: Path) -> Path | None:
    """The compiled bindings' file in one of the wheel's device folders, if any."""
    return next(iter(sorted(folder.glob("pybind*.so"))), None)


def _cuda_device(root: Path, cpu: Path) -> bool:
    """True when Open3D's own import would take its CUDA bindings: the wheel has them,
    the NVIDIA driver is installed, the bindings load and they count a device (the test
    of open3d/__init__.py, which loads the CPU library first to resolve the CUDA one's
    symbols)."""
    cuda = _bindings(root / "cuda")
    if cuda is None:
        return False
    try:  # no NVIDIA driver, no device: the 800 MB CUDA bindings are not loaded to count
        CDLL(NVIDIA_DRIVER)
    except OSError:
        return False
    try:
        CDLL(str(cpu))
        return int(CDLL(str(cuda)).open3d_core_cuda_device_count()) > 0
    except (OSError, AttributeError):
        return False
