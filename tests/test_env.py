"""The gymnasium environment: API conformance, seeding, policies and the recorder."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import auvsim  # noqa: F401  (registers auvsim/AUV-v0)
from auvsim.config import ScenarioConfig
from auvsim.data.reader import open_dataset
from auvsim.envs.env import AuvEnv, EpisodeRecorder, ManeuverPolicy
from auvsim.errors import ConfigError
from auvsim.physics.frames import euler_angles, quat_to_rot
from auvsim.runs.mission import MissionRun
from auvsim.runs.presets import preset
from beamsnet.data import load_windows


def test_registered_and_passes_the_gymnasium_checker_without_a_warning():
    env = gym.make("auvsim/AUV-v0")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # infinite bounds, out-of-space observations, ...
        check_env(env.unwrapped, skip_render_check=True)
    space = env.unwrapped.observation_space
    assert np.isfinite(space.low).all() and np.isfinite(space.high).all()
    assert env.unwrapped.dt == pytest.approx(0.1)
    env.close()


def test_observations_stay_within_their_bounds_and_bad_actions_are_refused():
    env = AuvEnv(max_episode_seconds=20.0)
    obs, _ = env.reset(seed=3)
    for _ in range(100):
        obs, *_ = env.step(np.array([1.0, 1.0, -1.0]))
        assert env.observation_space.contains(obs)
    for bad in (np.array([np.nan, 0, 0]), np.zeros(2), np.zeros((3, 1))):
        with pytest.raises(ValueError, match="action: expected 3 finite numbers"):
            env.step(bad)


def test_a_policys_random_waypoints_come_from_the_environments_np_random():
    env = AuvEnv(max_episode_seconds=5.0)
    policy = ManeuverPolicy(ScenarioConfig(name="random_waypoints", duration=600.0), env)

    def waypoints(seed):
        env.reset(seed=seed)
        policy.reset()
        return policy.maneuver.waypoints.copy()

    np.testing.assert_array_equal(waypoints(11), waypoints(11))
    assert not np.array_equal(waypoints(11), waypoints(12))


def rollout(env, seed, steps=50):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for k in range(steps):
        obs, *_ = env.step(np.array([0.6, np.sin(k / 5), 0.1], dtype=np.float32))
        out.append(obs)
    return np.array(out)


def test_the_same_seed_gives_the_same_episode():
    env = AuvEnv(max_episode_seconds=30.0)
    a, b, c = rollout(env, 7), rollout(env, 7), rollout(env, 8)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)  # other sensor noise


def reference_rollout(env, seed, actions):
    """The observations, infos and blocks of an episode as the environment defines them,
    computed with a ``MissionRun`` of the same mission directly: each action held over
    ``frame_skip`` physics steps, ``measure`` on them, and the observation read off the
    latest IMU sample, the latest ping and the state now."""
    env.reset(seed=seed)
    run = MissionRun(env.config, env.run.mission)
    vehicle = run.vehicle
    vehicle.reset(**run.scenario.initial_state())
    ping = np.zeros(8)
    out = []
    for k, action in enumerate(actions):
        command = np.clip(np.asarray(action, dtype=float), -1, 1) * env.limits
        traj = vehicle.run(np.tile(command, (env.frame_skip, 1)), (False, False, False))
        block = run.measure(np.arange(k * env.frame_skip, (k + 1) * env.frame_skip), traj)
        if len(block["dvl/time"]):
            ping = np.r_[np.nan_to_num(block["dvl/beam_velocity"][-1]),
                         block["dvl/valid"][-1]]
        state = vehicle.state(euler=True)
        obs = np.r_[block["imu/specific_force"][-1], block["imu/angular_rate"][-1], ping,
                    state["position_ned"][2]].astype(np.float32)
        out.append((np.clip(obs, env.observation_space.low, env.observation_space.high),
                    state, block))
    return out


def test_the_info_state_is_the_next_blocks_first_truth_row_bit_for_bit():
    # The state at a step's end is where the next step's physics starts: the info and the
    # truth compute it with the same arithmetic (frames.state_row and the physics loop).
    env = AuvEnv(preset("navigator"), max_episode_seconds=30.0)
    _, info = env.reset(seed=2)
    for k in range(40):
        *_, next_info = env.step(np.array([0.7, np.sin(k / 5), -0.3], dtype=np.float32))
        block = env.last_block
        for key in ("position_ned", "velocity_ned", "velocity_body", "quaternion",
                    "angular_rate"):
            assert block[f"truth/{key}"][0].tobytes() == info[key].tobytes(), (k, key)
        # The Euler angles are euler_angles' to rounding (libm's against numpy's arctan2).
        np.testing.assert_allclose(info["euler"], euler_angles(info["quaternion"]),
                                   rtol=0, atol=1e-15)
        rotation = quat_to_rot(info["quaternion"])
        np.testing.assert_allclose(info["velocity_body"], rotation.T @ info["velocity_ned"],
                                   rtol=0, atol=1e-15)
        info = next_info


@pytest.mark.parametrize("config", [None, preset("navigator")], ids=["paper-sim", "navigator"])
def test_the_observations_are_those_of_the_missions_sensors_bit_for_bit(config):
    env = AuvEnv(config, max_episode_seconds=30.0)
    actions = [np.array([0.7, np.sin(k / 4), 0.2 * np.cos(k / 9)], dtype=np.float32)
               for k in range(45)]  # 4.5 s: five pings, IMU and depth samples every step
    expected = reference_rollout(env, 5, actions)
    env.reset(seed=5)
    for action, (obs, info, block) in zip(actions, expected, strict=True):
        got, *_, got_info = env.step(action)
        assert got.tobytes() == obs.tobytes()  # bitwise: -0.0 and 0.0 differ too
        for key, value in info.items():
            assert np.asarray(got_info[key]).tobytes() == value.tobytes(), key
        assert env.last_block.keys() == block.keys()
        for path, value in block.items():
            np.testing.assert_array_equal(env.last_block[path], value, err_msg=path)


def test_full_rudder_action_reaches_the_fin_limit_and_time_truncates():
    env = AuvEnv(max_episode_seconds=5.0)
    env.reset(seed=0)
    steps, truncated = 0, False
    while not truncated and steps < 100:
        _, reward, terminated, truncated, info = env.step(np.array([0.5, 1.0, 0.0]))
        steps += 1
    assert steps == 50 and not terminated and reward == 0.0
    assert info["time"] == pytest.approx(5.0)
    assert env.run.vehicle.actuators[1] == pytest.approx(env.run.vehicle.hydro.rudder_max)
    with pytest.raises(gym.error.ResetNeeded, match="after the episode ended"):
        env.step(np.zeros(3))  # the vehicle does not fly on past its episode's end
    env.reset(seed=1)
    env.step(np.zeros(3))


@pytest.mark.parametrize("settings, said", [
    (dict(max_episode_seconds=0.0), "max_episode_seconds: expected a positive number"),
    (dict(max_episode_seconds=float("nan")), "max_episode_seconds: expected a positive"),
    (dict(max_episode_seconds="20"), "max_episode_seconds: expected a positive number"),
    (dict(frame_skip=True), "frame_skip: expected a whole number >= 1"),
    (dict(frame_skip=2.5), "frame_skip: expected a whole number >= 1"),
    (dict(config=20), "config: expected an auvsim Config"),
    (dict(config="nosuch.toml"), "config 'nosuch.toml': no such file, nor a preset's name; "
                                 "expected a TOML file's path or one of navigator, "),
    (dict(config="navigatr"), r"\(did you mean 'navigator'\?\)"),
])
def test_bad_environment_settings_are_refused_by_name(settings, said):
    with pytest.raises(ConfigError, match=said):
        AuvEnv(**settings)


def test_the_config_may_be_a_presets_name_or_a_toml_file(tmp_path):
    """As ``auvsim generate`` takes them: a preset's name, or a TOML file (read by
    ``auvsim.load_config``), each the same config as its Config."""
    from auvsim import load_config, preset

    assert AuvEnv(config="navigator").config == preset("navigator")
    toml = tmp_path / "mine.toml"
    toml.write_text('[dvl]\nbeam_angle_deg = 25.0\n\n[[missions]]\nname = "m"\n')
    env = AuvEnv(config=toml)
    assert env.config == load_config(str(toml)) and env.config.dvl.beam_angle_deg == 25.0


def test_a_policy_refuses_a_speed_or_depth_its_vehicle_cannot_hold():
    env = AuvEnv()
    with pytest.raises(ConfigError, match="speed 9 m/s is beyond what vehicle 'auv' can hold"):
        ManeuverPolicy(ScenarioConfig(name="zigzag", speed=9.0), env)
    # Below the environment's seafloor (60 m for paper-sim), as generate refuses it, where
    # it used to fly into the seabed.
    floor = env.config.seafloor.depth
    with pytest.raises(ConfigError, match=f"expected a depth above the seafloor at {floor:g}"):
        ManeuverPolicy(ScenarioConfig(name="straight", depth=floor + 20.0), env)


def test_a_numpy_frame_skip_is_a_whole_number_and_step_needs_a_reset():
    env = AuvEnv(frame_skip=np.int64(10), max_episode_seconds=np.float64(5.0))
    assert env.frame_skip == 10 and type(env.frame_skip) is int
    with pytest.raises(gym.error.ResetNeeded, match="expected reset"):
        env.step(np.zeros(3))
    env.reset(seed=0)
    env.step(np.zeros(3))


def test_the_recorder_refuses_a_bad_path_or_name_before_any_episode(tmp_path):
    """Said when it is made, not at close() after every episode has run."""
    (tmp_path / "notes.txt").write_text("mine")
    for path, name, what in ((tmp_path, "episode", "is a directory"),
                             (tmp_path / "notes.txt", "episode", "not HDF5"),
                             (tmp_path / "x.h5", "a/b", "expected a name without '/'")):
        with pytest.raises(ConfigError, match=what):
            EpisodeRecorder(AuvEnv(max_episode_seconds=10.0), path, name=name)
    assert (tmp_path / "notes.txt").read_text() == "mine"


def test_a_recorder_dropped_unclosed_says_its_episodes_were_not_written(tmp_path):
    """The episodes wait for close(); a recorder let go without it had lost them without a
    word. A with block closes it."""
    path = tmp_path / "forgot.h5"
    env = EpisodeRecorder(AuvEnv(max_episode_seconds=10.0), path)
    env.reset(seed=0)
    env.step(np.zeros(3))
    with pytest.warns(RuntimeWarning, match="1 episode.s. were not written to .*close"):
        del env
        import gc

        gc.collect()
    assert not path.exists()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with EpisodeRecorder(AuvEnv(max_episode_seconds=10.0), path) as env:
            env.reset(seed=0)
            env.step(np.zeros(3))
        del env
    with open_dataset(path) as f:
        assert sorted(f.missions) == ["episode_000"]


def test_the_recorder_and_the_policy_take_one_environment_in_one_line():
    """A vector environment's envs are in other processes: refused by name, where
    gymnasium's TypeError and an AttributeError ('no attribute run') had said it; so is a
    scenario's bare name for the policy."""
    envs = gym.make_vec("auvsim/AUV-v0", num_envs=2, vectorization_mode="sync")
    try:
        for make in (lambda: EpisodeRecorder(envs, "v.h5"),
                     lambda: ManeuverPolicy(ScenarioConfig(name="zigzag"), envs)):
            with pytest.raises(ConfigError, match="takes one auvsim environment.*got "
                                                  "SyncVectorEnv"):
                make()
    finally:
        envs.close()
    with pytest.raises(ConfigError, match="expected a ScenarioConfig .* got str 'zigzag'"):
        ManeuverPolicy("zigzag", AuvEnv(max_episode_seconds=10.0))


def test_a_render_mode_is_refused_by_the_vector_environment_as_by_one():
    """gymnasium passes render_mode to make_vec's entry point: refused in AuvEnv's words,
    where it had been a TypeError of an unexpected keyword."""
    with pytest.raises(ConfigError, match="render_mode: expected None, got 'rgb_array'"):
        gym.make_vec("auvsim/AUV-v0", num_envs=2, render_mode="rgb_array")


def test_a_manoeuvre_flies_as_a_policy_and_the_recorder_writes_a_dataset(tmp_path):
    path = tmp_path / "episodes.h5"
    env = EpisodeRecorder(AuvEnv(max_episode_seconds=120.0), path)
    policy = ManeuverPolicy(ScenarioConfig(name="turning_circle", speed=2.0,
                                           options={"lead_s": 10.0}), env)
    for seed in (1, 2):
        obs, info = env.reset(seed=seed)
        policy.reset()
        yaw = []
        while True:
            obs, _, terminated, truncated, info = env.step(policy(obs, info))
            yaw.append(info["euler"][2])
            if terminated or truncated:
                break
        turning = np.unwrap(yaw)[200:]  # after the lead-in and the rudder's travel
        assert np.all(np.diff(turning) > 0) and turning[-1] - turning[0] > np.pi
    env.close()
    with open_dataset(path) as f:
        assert sorted(f.missions) == ["episode_000", "episode_001"]
        m = f.missions["episode_000"]
        assert m.truth.time.shape == (12000,) and m.dvl.time.shape == (120,)
        np.testing.assert_array_equal(m.imu.index_of_dvl, np.arange(120) * 100)
        assert m.attrs["duration_s"] == pytest.approx(120.0)
        assert m.phases == [] and m.gravity == 9.81  # a policy flew it: no scripted phases
    windows = load_windows(path)  # BeamsNet reads what a policy flew
    assert len(windows.target) == 2 * (120 - 3)
    assert windows.accel.shape[1:] == (100, 3)


def vector_rollout(env, steps=15):
    """Observations and truncation flags of a 2-env vector environment flown with fixed
    actions, seeded 3 (its envs 3 and 4), over an episode end (1 s: 10 steps)."""
    obs, _ = env.reset(seed=3)
    out, truncated = [obs], []
    for k in range(steps):
        action = np.array([[0.6, np.sin(k / 5), 0.1], [0.4, -0.2, 0.0]], dtype=np.float32)
        obs, _, _, trunc, _ = env.step(action)
        out.append(obs)
        truncated.append(trunc)
    return np.array(out), np.array(truncated)


def test_sync_and_async_vector_environments_fly_the_same_episodes():
    sync = gym.make_vec("auvsim/AUV-v0", num_envs=2, vectorization_mode="sync",
                        max_episode_seconds=1.0)
    a, truncated = vector_rollout(sync)
    sync.close()
    env = gym.make_vec("auvsim/AUV-v0", num_envs=2, vectorization_mode="async",
                       max_episode_seconds=1.0)
    assert isinstance(env, gym.vector.AsyncVectorEnv)
    try:
        b, _ = vector_rollout(env)
    finally:
        env.close()
    assert not any(p.is_alive() for p in env.processes)  # no worker left behind
    np.testing.assert_array_equal(a, b)
    assert a.shape == (16, 2, 15) and truncated[9].all() and not truncated[:9].any()
    single = AuvEnv(max_episode_seconds=1.0)  # the first env is seeded 3, as alone
    single.reset(seed=3)
    alone = [single.step(np.array([0.6, np.sin(k / 5), 0.1], dtype=np.float32))[0]
             for k in range(10)]
    np.testing.assert_array_equal(a[1:11, 0], alone)


def test_render_mode_and_reset_options_are_refused_not_ignored():
    """gym.make passes render_mode: None is taken (render draws nothing), another mode is
    refused in one line; reset's options, which nothing reads, are refused too."""
    env = gym.make("auvsim/AUV-v0", render_mode=None, max_episode_seconds=5.0)
    env.reset(seed=0)
    assert env.unwrapped.render() is None
    with pytest.raises(ConfigError, match="render_mode: expected None, got 'rgb_array'"):
        AuvEnv(render_mode="rgb_array")
    with pytest.raises(ConfigError, match="options: expected None, got"):
        env.unwrapped.reset(options={"depth": 30.0})
