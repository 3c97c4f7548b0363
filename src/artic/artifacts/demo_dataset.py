"""The plan-demos output folder as files (docs/formats.md, Chapter 5): `demo_###.npz`
per planned demo (t, q_robot, qd_robot, q_object, ee_pose) and the `demos.json` index,
and the readers fit-dmp (joint trajectories) and policy search (state-action pairs) use.
Readers check every file against the folder's manifest; bad input is an InputError
naming the file."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from artic.artifacts.formats import read_json, read_npz, write_npz
from artic.artifacts.manifest import read_manifest, verify_file
from artic.errors import InputError


class DemoArrays(Protocol):
    """What a planned demo holds (`artic.planning.demos.Demo`): (T,) times and (T, .)
    robot positions and velocities, object configurations and end-effector poses."""

    @property
    def t(self) -> NDArray[np.float64]: ...
    @property
    def q_robot(self) -> NDArray[np.float64]: ...
    @property
    def qd_robot(self) -> NDArray[np.float64]: ...
    @property
    def q_object(self) -> NDArray[np.float64]: ...
    @property
    def ee_pose(self) -> NDArray[np.float64]: ...


DEMOS_JSON = "demos.json"
N_JOINTS = 7  # the KUKA iiwa's


def demo_name(index: int) -> str:
    return f"demo_{index:03d}.npz"


def write_demo(path: Path, demo: DemoArrays) -> None:
    """One planned demo as `demo_###.npz`."""
    write_npz(path, {"t": demo.t, "q_robot": demo.q_robot, "qd_robot": demo.qd_robot,
                     "q_object": demo.q_object, "ee_pose": demo.ee_pose})  # fmt: skip


@dataclass(frozen=True)
class Demo:
    """One successful demonstration: t (T,) s from 0; q (T, J) rad."""

    index: int
    file: str
    t: NDArray[np.float64]
    q: NDArray[np.float64]


@dataclass(frozen=True)
class DemoSet:
    task: str
    control_dt: float
    n_joints: int
    demos: list[Demo]
    n_listed: int


def load_demos(folder: Path, task: str, max_demos: int | None = None) -> DemoSet:
    """The successful demos of a plan-demos folder, checked; InputError names the file."""
    manifest = read_manifest(folder, expected_stage="plan-demos")
    index_path = verify_file(folder, manifest, DEMOS_JSON)
    try:
        info = read_json(index_path)
        listed = list(info["demos"])
        found_task, dt, n_joints = str(info["task"]), float(info["control_dt"]), info["n_joints"]
    except (ValueError, KeyError, TypeError) as err:
        raise InputError(f"{index_path}: malformed demos index ({err})") from None
    if found_task != task:
        raise InputError(
            f"demos: {folder} holds demos of task '{found_task}', expected '{task}' "
            f"(task={task}); pass the demos of task {task} or task={found_task}"
        )
    if not (isinstance(n_joints, int) and n_joints > 0 and dt > 0):
        raise InputError(f"{index_path}: n_joints and control_dt must be positive")
    ok = [d for d in listed if d.get("status") == "ok" and d.get("file")]
    if not ok:
        raise InputError(
            f"{index_path}: no successful demos ({len(listed)} listed, none with status ok)"
        )
    demos = [_load_demo(folder, manifest, d, n_joints, dt) for d in ok[:max_demos]]
    return DemoSet(found_task, dt, n_joints, demos, len(listed))


def _load_demo(
    folder: Path, manifest: Any, entry: dict[str, Any], n_joints: int, dt: float
) -> Demo:
    path = verify_file(folder, manifest, str(entry["file"]))
    try:
        data = read_npz(path)
        t, q = data["t"].astype(np.float64), data["q_robot"].astype(np.float64)
    except (OSError, ValueError, KeyError) as err:
        raise InputError(f"{path}: not a demo file with t and q_robot ({err})") from None
    if q.ndim != 2 or q.shape[1] != n_joints:
        raise InputError(f"{path}: q_robot has shape {q.shape}, expected (T, {n_joints}) joints")
    if t.shape != (q.shape[0],) or t.shape[0] < 2:
        raise InputError(f"{path}: t has shape {t.shape}, expected ({q.shape[0]},), T >= 2")
    if not (np.isfinite(t).all() and np.isfinite(q).all()):
        raise InputError(f"{path}: t and q_robot must be finite (found NaN or inf)")
    if not np.allclose(np.diff(t), dt, rtol=1e-6, atol=1e-9):
        raise InputError(f"{path}: t is not uniform with the control dt {dt} s of {DEMOS_JSON}")
    return Demo(int(entry.get("index", 0)), str(entry["file"]), t - t[0], q)


def load_demo_pairs(folder: Path, task: str, dof: int) -> tuple[np.ndarray, np.ndarray]:
    """(obs (M, 7 + dof), actions (M, 7)) of every successful demo of a plan-demos folder:
    obs = [q_robot, q_object], action = qd_robot."""
    manifest = read_manifest(folder, expected_stage="plan-demos")
    index = verify_file(folder, manifest, DEMOS_JSON)
    try:
        info = read_json(index)
        found, entries = str(info["task"]), list(info["demos"])
    except (ValueError, KeyError, TypeError) as err:
        raise InputError(f"{index}: malformed demos index ({err})") from None
    if found != task:
        raise InputError(f"demos: {folder} holds demos of task '{found}', expected '{task}'")
    obs, act = [], []
    for entry in entries:
        if entry.get("status") != "ok" or not entry.get("file"):
            continue
        path = verify_file(folder, manifest, str(entry["file"]))
        try:
            data = read_npz(path)
            q, qd, qo = data["q_robot"], data["qd_robot"], data["q_object"]
        except (OSError, ValueError, KeyError) as err:
            raise InputError(
                f"{path}: not a demo with q_robot, qd_robot, q_object ({err})"
            ) from None
        qo = qo.reshape(len(qo), -1)
        if q.ndim != 2 or q.shape[1] != N_JOINTS or qd.shape != q.shape:
            raise InputError(f"{path}: q_robot/qd_robot must be (T, {N_JOINTS}), got {q.shape}")
        if qo.shape != (len(q), dof):
            raise InputError(f"{path}: q_object must be ({len(q)}, {dof}), got {qo.shape}")
        obs.append(np.hstack([q, qo]))
        act.append(qd)
    if not obs:
        raise InputError(f"{index}: no successful demos")
    o, a = np.vstack(obs), np.vstack(act)
    if not (np.isfinite(o).all() and np.isfinite(a).all()):
        raise InputError(f"demos: {folder} has NaN or inf in q_robot, qd_robot or q_object")
    return o, a
