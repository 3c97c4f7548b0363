"""One interface over the depth renderers, and their registry.

A backend renders an `ArticulatedObject` at a configuration from the pinhole camera of
`geometry.camera` (at the origin, looking down +x, +z up). Backend modules import their
simulator only when `make_backend` asks for them.
"""

from __future__ import annotations

import importlib
from abc import ABC, abstractmethod
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import NamedTuple, Protocol, Self

import numpy as np
from numpy.typing import NDArray

from artic.geometry.camera import CameraIntrinsics
from artic.objects.model import ArticulatedObject


class RenderedImage(NamedTuple):
    """depth: (H, W) float32 metres along the optical axis, 0 where no surface.
    part_mask: (H, W) uint8, 0 background, k + 1 where link k is seen."""

    depth: NDArray[np.float32]
    part_mask: NDArray[np.uint8]


class DepthBackend(Protocol):
    camera: CameraIntrinsics

    def render(
        self,
        obj: ArticulatedObject,
        configuration: NDArray[np.float64],
        urdf_path: Path | None = None,
    ) -> RenderedImage: ...

    def render_many(
        self,
        obj: ArticulatedObject,
        configurations: NDArray[np.float64],
        urdf_path: Path | None = None,
    ) -> list[RenderedImage]:
        """One image per row of `configurations` (n, dof): the object across its
        articulation (what render-depth asks for; backends may batch the work)."""
        ...

    def close(self) -> None: ...

    def __enter__(self) -> DepthBackend: ...

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...


Factory = Callable[..., DepthBackend]

#: backend name -> module that registers it (imported on first use)
_MODULES = {"raycast": "artic.render.raycast", "pybullet": "artic.render.pybullet_backend"}
_REGISTRY: dict[str, Factory] = {}


def register_backend(name: str) -> Callable[[Factory], Factory]:
    """Class decorator: make a backend available to `make_backend` under `name`."""

    def add(factory: Factory) -> Factory:
        _REGISTRY[name] = factory
        return factory

    return add


def make_backend(name: str, camera: CameraIntrinsics, *, threads: int = 1) -> DepthBackend:
    """A backend by name ("raycast" or "pybullet"); `threads` for ray casting."""
    if name not in _MODULES:
        raise KeyError(f"unknown render backend '{name}' (known: {', '.join(sorted(_MODULES))})")
    importlib.import_module(_MODULES[name])
    return _REGISTRY[name](camera, threads=threads)


class BackendBase(ABC):
    """Context-manager plumbing shared by the backends, and `render_many` as a loop."""

    @abstractmethod
    def render(
        self,
        obj: ArticulatedObject,
        configuration: NDArray[np.float64],
        urdf_path: Path | None = None,
    ) -> RenderedImage:
        """One image of `obj` at `configuration` (dof,)."""

    def render_many(
        self,
        obj: ArticulatedObject,
        configurations: NDArray[np.float64],
        urdf_path: Path | None = None,
    ) -> list[RenderedImage]:
        return [self.render(obj, q, urdf_path) for q in np.asarray(configurations)]

    def close(self) -> None:
        return None

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
