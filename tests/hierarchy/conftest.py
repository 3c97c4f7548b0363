"""Chapter 4 network tests run torch on one thread: small tensors, a shared 2-core machine
(a second thread mostly waits), and the same float reductions in every run."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import torch


@pytest.fixture(autouse=True)
def _one_thread() -> Iterator[None]:
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)
