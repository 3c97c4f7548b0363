"""One measurement of `make bench` part 6, in a fresh process: the Chapter 3 MDN's
training step and batch forward with the kernels artic pins, or with each library's own
choice for this CPU. Usage: python bench/numerics_child.py pinned|native
Prints one JSON line: training images/s, forward images/s (medians) and a hash of the
weights after the steps (the pins change the numbers, not just the speed)."""

from __future__ import annotations

import hashlib
import json
import os
import statistics
import sys
import time

from artic.reproducibility import PINNED, numerics_record, pin_numerics

MODE = sys.argv[1]
if MODE == "pinned":
    pin_numerics()
else:
    for name in PINNED:
        os.environ.pop(name, None)

import torch  # noqa: E402

from artic.kinematics.mdn import KinematicsMDN, mdn_nll  # noqa: E402
from artic.kinematics.preprocess import SIDE_FEATURES  # noqa: E402

torch.set_num_threads(2)  # train.threads' default
torch.manual_seed(0)
gen = torch.Generator().manual_seed(1)
model = KinematicsMDN(8, 20, 32, input_size=64).to(memory_format=torch.channels_last)
opt = torch.optim.Adam(model.parameters(), 1e-3)
train, forward = [], []
for step in range(12):
    x = torch.rand(64, 1, 64, 64, generator=gen).contiguous(memory_format=torch.channels_last)
    side, y = torch.rand(64, SIDE_FEATURES, generator=gen), torch.randn(64, 8, generator=gen)
    t0 = time.perf_counter()
    loss = mdn_nll(model(x, side), y)
    opt.zero_grad()
    loss.backward()
    opt.step()
    t1 = time.perf_counter()
    with torch.no_grad():
        model(x, side)
    t2 = time.perf_counter()
    if step >= 2:  # warm-up
        train.append(64 / (t1 - t0))
        forward.append(64 / (t2 - t1))
weights = hashlib.sha256(b"".join(p.detach().numpy().tobytes() for p in model.parameters()))
print(json.dumps({
    "mode": MODE,
    "numerics": numerics_record(),
    "train_images_per_s": statistics.median(train),
    "forward_images_per_s": statistics.median(forward),
    "weights_sha256": weights.hexdigest()[:16],
}))  # fmt: skip
