"""Same seed, same bytes on any x86-64 CPU: the numerical libraries' kernels, pinned.

MKL, PyTorch's own kernels, oneDNN (PyTorch's convolutions), OpenBLAS (NumPy's and
SciPy's linear algebra) and NumPy's vectorised functions each choose their kernels by the
CPU they run on at load time. On a CPU with AVX-512 they take other kernels than on one
with AVX2 only, and the results differ in the last bits (measured on an AVX-512 Xeon, in
docs/architecture.md: every one of the five changes a training run's weights or a
matrix product), which then compound over training steps and rollouts. MKL's
small-matrix products also depend on the alignment of their operands unless its
reproducibility mode is strict.

`pin_numerics` sets, for this process and the worker processes it starts, the variables
that make all five use their AVX2 kernels (and MKL its strict reproducible mode), on
every CPU that has AVX2 and FMA (Intel since 2013, AMD since 2015). It must run before
NumPy or PyTorch are imported: the `artic` command calls it first thing. A variable the
user has set is left as it is (a cluster user may trade reproducibility across CPUs for
speed, e.g. `ONEDNN_MAX_CPU_ISA=ALL`); `numerics_record` tells which values were in force,
and every manifest records it.
"""

from __future__ import annotations

import os
import platform
import sys
from collections.abc import MutableMapping
from pathlib import Path

#: the AVX2 kernels of each library, and MKL's strict reproducible mode
PINNED: dict[str, str] = {
    "MKL_CBWR": "AVX2,STRICT",
    "ATEN_CPU_CAPABILITY": "avx2",
    "ONEDNN_MAX_CPU_ISA": "AVX2",
    "OPENBLAS_CORETYPE": "Haswell",
    "NPY_DISABLE_CPU_FEATURES": (
        "AVX512F AVX512CD AVX512_KNL AVX512_KNM AVX512_SKX AVX512_CLX AVX512_CNL "
        "AVX512_ICL AVX512_SPR"
    ),
}

_NUMERIC_MODULES = ("numpy", "torch", "scipy")


def cpu_supports_pins(cpuinfo: Path = Path("/proc/cpuinfo")) -> bool:
    """Whether this is an x86-64 CPU with AVX2 and FMA (what the pinned kernels need)."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return False
    try:
        text = cpuinfo.read_text()
    except OSError:
        return False
    for line in text.splitlines():
        if line.startswith("flags"):
            flags = set(line.partition(":")[2].split())
            return {"avx2", "fma"} <= flags
    return False


def pin_numerics(environ: MutableMapping[str, str] | None = None) -> bool:
    """Set each variable of `PINNED` that is not set yet; returns whether the pins apply
    (False on a CPU without AVX2/FMA or not x86-64, where nothing is set). Call before
    importing NumPy or PyTorch; a library already loaded keeps the kernels it chose."""
    env = os.environ if environ is None else environ
    if not cpu_supports_pins():
        return False
    for name, value in PINNED.items():
        env.setdefault(name, value)
    return True


def numerics_loaded_too_early() -> list[str]:
    """Numerical modules already imported (pins set now would not reach them)."""
    return [m for m in _NUMERIC_MODULES if m in sys.modules]


def numerics_record(environ: MutableMapping[str, str] | None = None) -> str:
    """The values in force, as one line for a manifest: `NAME=VALUE ...` in `PINNED`'s
    order (`NAME=` when unset, e.g. on a CPU without AVX2)."""
    env = os.environ if environ is None else environ
    return " ".join(f"{name}={env.get(name, '')}" for name in PINNED)
