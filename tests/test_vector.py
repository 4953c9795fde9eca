"""AuvVectorEnv: the same episodes, infos and autoresets as gymnasium's SyncVectorEnv, bit
for bit; its workers and shared memory gone after close, a worker's error and a killed
parent."""

import gc
import multiprocessing as mp
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import auvsim  # noqa: F401  (registers auvsim/AUV-v0)
from auvsim.envs.vector import AuvVectorEnv

ROOT = Path(__file__).resolve().parents[1]


def actions(k: int, num_envs: int) -> np.ndarray:
    """Varying actions for step ``k``, different in each env."""
    rng = np.random.default_rng(k)
    return rng.uniform(-1.0, 1.0, (num_envs, 3)).astype(np.float32)


def rollout(env, steps: int = 25) -> list[tuple]:
    """Everything ``env`` returns: its reset(seed=7) and ``steps`` steps (1 s episodes of
    10 steps: two autoresets)."""
    out = [env.reset(seed=7)]
    for k in range(steps):
        out.append(env.step(actions(k, env.num_envs)))
    return out


def assert_same(a, b) -> None:
    """Two results of reset or step identical: arrays bitwise, with dtype and shape;
    infos key by key (and in the same order), masks included."""
    assert len(a) == len(b)
    for x, y in zip(a[:-1], b[:-1], strict=True):
        assert x.dtype == y.dtype and x.shape == y.shape
        assert x.tobytes() == y.tobytes()
    info_a, info_b = a[-1], b[-1]
    assert list(info_a) == list(info_b)
    for key in info_a:
        assert info_a[key].dtype == info_b[key].dtype, key
        assert info_a[key].tobytes() == info_b[key].tobytes(), key


@pytest.fixture(scope="module")
def sync_rollout():
    env = gym.make_vec("auvsim/AUV-v0", num_envs=3, vectorization_mode="sync",
                       max_episode_seconds=1.0)
    out = rollout(env)
    env.close()
    return out


def test_workers_fly_the_sync_vector_envs_episodes_and_leave_nothing_after_close(
        sync_rollout):
    env = gym.make_vec("auvsim/AUV-v0", num_envs=3, vectorization_mode="vector_entry_point",
                       workers=2, max_episode_seconds=1.0)  # 2 envs and 1: uneven
    assert isinstance(env, AuvVectorEnv) and env.workers == 2
    assert env.metadata["autoreset_mode"] == gym.vector.AutoresetMode.NEXT_STEP
    processes = list(env._processes)
    segment = Path("/dev/shm") / env._shm.name.lstrip("/")
    assert segment.exists() and all(p.is_alive() for p in processes)
    out = rollout(env)
    for mine, theirs in zip(out, sync_rollout, strict=True):
        assert_same(mine, theirs)
    truncations = np.array([step[3] for step in out[1:]])
    assert truncations[[9, 20]].all() and truncations.sum() == 6  # two autoresets
    for step in out[1:]:
        assert env.observation_space.contains(step[0])
    assert env.single_observation_space.contains(out[-1][0][0])
    assert env.action_space.shape == (3, 3)
    env.close()
    assert not any(p.is_alive() for p in processes)
    assert not mp.active_children()
    assert not segment.exists()
    env.close()  # a second close does nothing


def test_in_process_envs_fly_the_same_episodes(sync_rollout):
    env = gym.make_vec("auvsim/AUV-v0", num_envs=3, workers=0,  # the default mode
                       max_episode_seconds=1.0)
    assert isinstance(env, AuvVectorEnv) and not env.worker_pids
    out = rollout(env)
    env.close()
    for mine, theirs in zip(out, sync_rollout, strict=True):
        assert_same(mine, theirs)


def test_reset_mask_resets_those_envs_as_sync_does():
    def masked(env):
        env.reset(seed=1)
        for k in range(3):
            env.step(actions(k, 3))
        return env.reset(seed=20, options={"reset_mask": np.array([True, False, True])})

    sync = gym.make_vec("auvsim/AUV-v0", num_envs=3, vectorization_mode="sync")
    expected = masked(sync)
    sync.close()
    env = AuvVectorEnv(num_envs=3, workers=0)
    assert_same(masked(env), expected)
    assert not expected[1]["_time"][1]
    env.close()


def test_bad_actions_are_refused_and_an_error_in_a_worker_closes_the_env():
    env = AuvVectorEnv(num_envs=2, workers=2, max_episode_seconds=1.0)
    processes = list(env._processes)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"actions: expected an array of shape \(2, 3\).*"
                                         r"got shape \(3,\)"):
        env.step(np.zeros(3))
    env.step(np.zeros((2, 3)))  # still usable after the refusal
    bad = np.zeros((2, 3))
    bad[1, 0] = np.nan
    with pytest.raises(ValueError, match=r"actions: expected finite numbers.*\[nan, 0.0, "
                                         r"0.0\] for env 1"):
        env.step(bad)
    env.step(np.zeros((2, 3)))  # refused before any env stepped: still usable
    assert not env.closed
    # An error inside an env (a seed gymnasium refuses) closes the vector env.
    with pytest.raises(gym.error.Error, match="greater or equal to zero") as caught:
        env.reset(seed=[0, -1])
    assert caught.value.__notes__ == ["in env 1 of the AuvVectorEnv"]
    assert env.closed
    assert not any(p.is_alive() for p in processes) and not mp.active_children()
    with pytest.raises(RuntimeError, match="closed"):
        env.step(np.zeros((2, 3)))


def test_a_killed_parent_leaves_no_worker_and_no_shared_memory():
    script = textwrap.dedent("""
        import os, signal
        from auvsim.envs.vector import AuvVectorEnv
        if __name__ == "__main__":
            env = AuvVectorEnv(num_envs=2, workers=2)
            print(env._shm.name, *env.worker_pids, flush=True)
            os.kill(os.getpid(), signal.SIGKILL)
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            timeout=60, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert result.returncode == -9, result.stderr
    name, *pids = result.stdout.split()
    pids = [int(p) for p in pids]
    assert len(pids) == 2
    segment = Path("/dev/shm") / name.lstrip("/")

    def alive(pid: int) -> bool:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        try:  # a zombie (dead, not yet reaped by the forkserver) counts as gone
            with open(f"/proc/{pid}/stat") as f:
                return f.read().split(")")[-1].split()[0] != "Z"
        except FileNotFoundError:
            return False

    deadline = time.monotonic() + 5.0
    while (any(alive(p) for p in pids) or segment.exists()) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(alive(p) for p in pids)
    assert not segment.exists()  # unlinked by multiprocessing's resource tracker


@pytest.mark.parametrize("gone", [False, True], ids=["dying", "gone"])
def test_a_dead_worker_is_reported_and_the_env_closed(gone):
    """Killed and stepped at once (the step's message reaches a dying worker), or stepped
    once it is gone (its end of the pipe closed): one RuntimeError, the env closed."""
    env = AuvVectorEnv(num_envs=2, workers=2)
    env.reset(seed=0)
    process = env._processes[1]
    os.kill(process.pid, signal.SIGKILL)
    if gone:
        process.join(timeout=10.0)
        assert not process.is_alive()
    with pytest.raises(RuntimeError, match=r"worker 1 \(pid \d+\) died, exit code -9"):
        env.step(np.zeros((2, 3)))
    assert env.closed and not mp.active_children()


def test_a_forgotten_env_stops_its_workers_when_collected():
    env = AuvVectorEnv(num_envs=2, workers=2)
    processes = list(env._processes)
    segment = Path("/dev/shm") / env._shm.name.lstrip("/")
    del env
    gc.collect()
    assert not any(p.is_alive() for p in processes) and not mp.active_children()
    assert not segment.exists()


def test_ctrl_c_during_this_processs_own_slice_closes_the_env():
    """A KeyboardInterrupt while this process steps its own envs (the workers' answers
    then unread) closes the env rather than leaving its pipes out of step."""
    env = AuvVectorEnv(num_envs=2, workers=1)
    env.reset(seed=0)

    def interrupted(action):
        raise KeyboardInterrupt

    env._slice.envs[0].step = interrupted
    with pytest.raises(KeyboardInterrupt):
        env.step(np.zeros((2, 3)))
    assert env.closed and not mp.active_children()


def test_a_script_that_makes_the_env_unguarded_is_told_why_its_worker_died(tmp_path):
    """A worker imports the main script again as it starts; one that makes the env at its
    top level made another there, which multiprocessing refused, and the parent said only
    "worker 0 died, exit code 1"."""
    script = tmp_path / "unguarded.py"
    script.write_text("import gymnasium as gym\n"
                      "import auvsim.envs\n"
                      "env = gym.make_vec('auvsim/AUV-v0', num_envs=2, workers=1)\n"
                      "env.close()\n")
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=300, cwd=tmp_path)
    assert done.returncode == 1
    assert done.stderr.splitlines()[-1].endswith(
        "died, exit code 1 as it started (if a script makes the env at its top level, it "
        "must do so under if __name__ == \"__main__\":, as the worker imports it again)"), \
        done.stderr[-1000:]
