"""Gymnasium conventions of the task environments: registration at import of
artic.sim.envs (plain and `module:env` ids, max_episode_steps, idempotent), the
normalised action box under check_env with every warning an error, rgb_array frames
from the PyBullet camera, and the animated GIF of frames."""

from __future__ import annotations

import io
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from PIL import Image

from artic.sim.camera import CameraConfig, encode_gif
from artic.sim.envs import ENV_IDS, ArticTaskEnv, env_id, register_envs
from artic.sim.tasks import TASKS, get_task

SMALL = CameraConfig(width=64, height=48)


def test_every_task_is_registered_with_its_horizon():
    assert ENV_IDS == ["artic/Drawer-v0", "artic/Microwave-v0", "artic/TBall-v0",
                       "artic/Drawer_light-v0"]  # fmt: skip
    assert [env_id(t) for t in TASKS] == ENV_IDS
    for task in TASKS:
        spec = gym.spec(env_id(task))
        assert spec.max_episode_steps == get_task(task).horizon
        assert spec.kwargs == {"task": task}


def test_registering_again_neither_warns_nor_fails():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert register_envs() == ENV_IDS
    code = (  # a second import of the module (reload) registers nothing new, silently
        "import importlib, warnings; import artic.sim.envs as m; "
        "warnings.simplefilter('error'); importlib.reload(m); "
        "assert m.register_envs() == m.ENV_IDS"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_make_by_id_and_by_module_colon_id_in_a_fresh_process():
    code = (
        "import gymnasium as gym, warnings; warnings.simplefilter('error'); "
        "env = gym.make('artic.sim.envs:artic/Drawer-v0', seed=0); "
        "obs, _ = env.reset(seed=0); assert obs.shape == (8,); "
        "assert env.spec.max_episode_steps == 80; env.close(); "
        "env = gym.make('artic/Microwave-v0'); assert env.unwrapped.task.name == 'microwave'"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_time_limit_of_make_truncates_at_the_horizon():
    env = gym.make("artic/TBall-v0", seed=0, normalised_actions=True)
    try:
        env.reset(seed=1)
        zero = np.zeros(7, dtype=np.float32)
        flags = [env.step(zero)[3] for _ in range(60)]
        assert flags == [False] * 59 + [True]
    finally:
        env.close()


@pytest.mark.parametrize("env_name", ["artic/Drawer-v0", "artic/Microwave-v0", "artic/TBall-v0"])
def test_normalised_actions_pass_check_env_without_any_warning(env_name):
    env = gym.make(env_name, normalised_actions=True, render_mode="rgb_array", camera=SMALL)
    try:
        assert env.action_space == gym.spaces.Box(-1.0, 1.0, (7,), np.float32)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            check_env(env.unwrapped)  # the render check included
    finally:
        env.close()


def test_normalised_actions_are_rescaled_to_the_speed_limits():
    physical = ArticTaskEnv("drawer", seed=0)
    normalised = ArticTaskEnv("drawer", seed=0, normalised_actions=True)
    limit = physical.action_box.high.astype(np.float64)
    assert np.array_equal(normalised.action_box.high, physical.action_space.high)
    actions = np.random.default_rng(3).uniform(-1.0, 1.0, (15, 7))
    try:
        runs = []
        for env, scale in ((physical, limit), (normalised, 1.0)):
            obs, _ = env.reset(seed=5)
            out, rewards = [obs], []
            for a in actions:
                # the same joint velocities: rad/s for one, fractions of the limits for the other
                obs, reward, *_ = env.step(a * scale)
                out.append(obs)
                rewards.append(reward)
            runs.append((np.stack(out), np.asarray(rewards)))
        np.testing.assert_allclose(runs[0][0], runs[1][0], atol=1e-6)
        np.testing.assert_allclose(runs[0][1], runs[1][1], rtol=1e-6)  # Eq. 5.1 in rad/s
    finally:
        physical.close()
        normalised.close()


def _episode(env: ArticTaskEnv, render: bool) -> tuple[bytes, list[np.ndarray]]:
    actions = np.random.default_rng(7).uniform(-1.0, 1.0, (10, 7)).astype(np.float32)
    obs, _ = env.reset(seed=2)
    states, frames = [obs], []
    for a in actions:
        if render:
            frames.append(env.render())
        obs, *_ = env.step(a)
        states.append(obs)
    return np.stack(states).tobytes(), frames


@pytest.mark.parametrize("task", ["drawer", "tball"])
def test_rgb_array_frames_are_deterministic_and_do_not_change_the_simulation(task):
    plain = ArticTaskEnv(task, seed=0)
    filmed = ArticTaskEnv(task, seed=0, render_mode="rgb_array", camera=SMALL)
    again = ArticTaskEnv(task, seed=0, render_mode="rgb_array", camera=SMALL)
    try:
        assert plain.render() is None and plain._camera is None  # render_mode=None: no camera
        states, _ = _episode(plain, render=False)
        filmed_states, frames = _episode(filmed, render=True)
        again_states, frames_again = _episode(again, render=True)
        assert filmed_states == states == again_states
        assert all(f.shape == (48, 64, 3) and f.dtype == np.uint8 for f in frames)
        assert b"".join(f.tobytes() for f in frames) == b"".join(f.tobytes() for f in frames_again)
        assert not np.array_equal(frames[0], frames[-1])  # the robot moved
        assert len(np.unique(frames[0].reshape(-1, 3), axis=0)) > 10  # a scene, not a blank
    finally:
        for env in (plain, filmed, again):
            env.close()


def test_frames_show_the_object_meshes():
    # the drawer is built from collision meshes only; the camera draws visual copies
    cfg = CameraConfig(width=96, height=72)
    env = ArticTaskEnv("drawer", seed=0, render_mode="rgb_array", camera=cfg)
    try:
        env.reset(seed=0)
        frame = env.render()
        assert frame is not None
        r, g, b = (frame[:, :, i].astype(int) for i in range(3))
        beige = (r - b > 25) & (r - g < 30) & (g - b > 10)  # the body and drawer, lit
        assert beige.sum() > 30  # of 96 x 72 pixels: the robot is blue and orange
    finally:
        env.close()


def test_bad_render_mode_is_refused():
    with pytest.raises(ValueError, match="render_mode"):
        ArticTaskEnv("tball", render_mode="human")


def test_gif_bytes_are_deterministic_and_decode_to_the_frames():
    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 255, (24, 32, 3), dtype=np.uint8) for _ in range(3)]
    frames = [np.repeat(np.repeat(f[::4, ::4], 4, 0), 4, 1) for f in frames]  # few colours
    data = encode_gif(frames, fps=10)
    assert data == encode_gif([f.copy() for f in frames], fps=10)
    image = Image.open(io.BytesIO(data))
    assert image.format == "GIF" and image.n_frames == 3 and image.size == (32, 24)
    assert image.info["duration"] == 100 and image.info["loop"] == 0
    image.seek(1)
    assert np.array_equal(np.asarray(image.convert("RGB")), frames[1])
    with pytest.raises(ValueError, match="at least one frame"):
        encode_gif([], fps=10)


def test_ball_position_is_what_the_camera_draws():
    from artic.sim.scene import ball_start

    env = ArticTaskEnv("tball", seed=0)
    drawer = ArticTaskEnv("drawer", seed=0)
    try:
        env.reset(seed=0)
        start = ball_start(env.task.scene)
        np.testing.assert_allclose(env.world.ball_position(), start, atol=1e-9)
        for _ in range(5):
            env.step(np.zeros(7, dtype=np.float32))
        position = env.world.ball_position()
        assert position is not None
        assert position[1] - start[1] == pytest.approx(env.world.object_q()[0])
        assert drawer.world.ball_position() is None
    finally:
        env.close()
        drawer.close()
