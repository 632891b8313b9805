"""10 Hz chunks -> 50 Hz targets: drop 3, execute 5, interpolate; the runner never blocks and holds on failure."""

import threading
import time

import numpy as np
import pytest

from toddlerbot.dp.chunker import ActionChunker
from toddlerbot.dp.runner import ChunkPolicyRunner

CHUNK = np.arange(16, dtype=float)[:, None] * np.array([1.0, -2.0])  # action i = (i, -2i)


def test_chunker_drops_three_executes_five_and_interpolates_to_50_hz():
    plan = ActionChunker(latency_drop=3, n_action_steps=5, policy_dt=0.1, control_dt=0.02).plan(CHUNK)
    assert plan.shape == (25, 2)  # 5 actions x 5 control steps
    np.testing.assert_allclose(plan[::5], CHUNK[3:8])  # each executed action on its own 10 Hz tick
    np.testing.assert_allclose(plan[:5, 0], [3.0, 3.2, 3.4, 3.6, 3.8])  # linear between ticks
    np.testing.assert_allclose(plan[-1], [7.8, -15.6])
    with pytest.raises(ValueError, match="horizon > 8"):
        ActionChunker().plan(CHUNK[:8])
    with pytest.raises(ValueError, match="whole multiple"):
        ActionChunker(policy_dt=0.1, control_dt=0.03)


def obs(k: int) -> dict:
    return {"observation.state": np.array([float(k)])}


def test_runner_feeds_the_model_10_hz_observations_and_plays_consecutive_chunks_seamlessly():
    seen = []

    def infer(history):
        seen.append(history["observation.state"][:, 0].copy())
        return CHUNK + 100 * len(seen)

    runner = ChunkPolicyRunner(infer, ActionChunker(), n_obs_steps=2, initial_targets=np.zeros(2), synchronous=True)
    targets = np.array([runner.step(obs(k)) for k in range(15 + 25 + 25)])
    # the history holds 10 Hz samples (every 5th control step), the first one padded like the dataset
    np.testing.assert_array_equal(seen[0], [0.0, 0.0])
    np.testing.assert_array_equal(seen[1], [20.0, 25.0])
    # hold the initial targets for the 3 dropped policy steps, then chunk 1, then chunk 2 right after it
    assert np.all(targets[:15] == 0.0)
    np.testing.assert_allclose(targets[15:40], ActionChunker().plan(CHUNK + 100))
    np.testing.assert_allclose(targets[40:65], ActionChunker().plan(CHUNK + 200))
    assert runner.status.chunks_used == 2 and runner.status.failures == 0


def test_failed_or_non_finite_inference_holds_the_last_safe_targets():
    calls = []

    def infer(history):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("camera frame missing")
        if len(calls) == 3:
            return CHUNK * np.nan
        return CHUNK

    runner = ChunkPolicyRunner(infer, ActionChunker(), 2, np.zeros(2), synchronous=True)
    targets = np.array([runner.step(obs(k)) for k in range(80)])
    last_of_first_plan = ActionChunker().plan(CHUNK)[-1]
    np.testing.assert_allclose(targets[39], last_of_first_plan)
    np.testing.assert_allclose(targets[40:50], np.tile(last_of_first_plan, (10, 1)))  # held, not garbage
    assert runner.status.failures == 2 and "non-finite" in runner.status.last_error
    assert np.isfinite(targets).all()
    # the fourth request (at 0.7 s) succeeds and its plan starts on its own tick, 0.3 s later
    np.testing.assert_allclose(targets[50:75], ActionChunker().plan(CHUNK))


def test_slow_inference_on_the_worker_never_blocks_the_control_loop_and_stale_chunks_are_dropped():
    release = threading.Event()

    def infer(history):
        release.wait(timeout=5.0)
        return CHUNK

    runner = ChunkPolicyRunner(infer, ActionChunker(), 2, np.array([0.5, 0.5]), stale_after_s=0.2)
    start = time.perf_counter()
    targets = [runner.step(obs(k)) for k in range(50)]  # 1 s of control while inference hangs
    elapsed = time.perf_counter() - start
    release.set()
    assert elapsed < 0.5  # the loop did not wait for the model
    assert all(np.array_equal(t, [0.5, 0.5]) for t in targets) and runner.status.holding
    deadline = time.perf_counter() + 5.0
    while runner.status.stale_dropped == 0 and time.perf_counter() < deadline:
        runner.step(obs(50))
        time.sleep(0.001)
    assert runner.status.stale_dropped == 1  # 50+ control steps (> 0.2 s) old when it arrived: not used
    runner.close()


def test_a_chunk_of_the_wrong_width_is_a_failure_not_a_target():
    runner = ChunkPolicyRunner(lambda history: np.zeros((16, 3)), ActionChunker(), 2, np.ones(2), synchronous=True)
    targets = np.array([runner.step(obs(k)) for k in range(20)])
    assert targets.shape == (20, 2) and np.all(targets == 1.0)
    # retried on every 10 Hz tick (0, 5, 10, 15), each refused
    assert runner.status.failures == 4 and "expected (horizon, 2)" in runner.status.last_error
