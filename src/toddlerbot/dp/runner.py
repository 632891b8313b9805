"""The control-loop side of a chunk policy: 10 Hz observations in, 50 Hz targets out, inference on a worker thread.

`ChunkPolicyRunner.step` is called once per control period and never waits for inference. Every ``substeps``
control steps it adds the observation to the 10 Hz history (the model is fed at the rate it was trained at, not
at 50 Hz). When the executing plan has ``latency_drop`` policy steps left it asks the worker for the next chunk
(so, if inference takes less than that, the new plan starts exactly where the old one ends). A chunk is used
from the control step its ``chunk[latency_drop]`` belongs to; one that arrives late has its passed steps skipped;
one older than ``stale_after_s`` is discarded. Until a usable chunk is there - at the start, after a failed or
non-finite inference, or while inference is stale - the last target sent is held (the last safe targets).
numpy only: the model is behind the ``infer`` callable.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from toddlerbot.dp.chunker import ActionChunker

Infer = Callable[[dict[str, np.ndarray]], np.ndarray]
"""Observation history (key -> (n_obs, ...) array, oldest first) -> action chunk (horizon, A)."""


@dataclass
class RunnerStatus:
    holding: bool = True
    """True when the last target was a hold (no usable chunk)."""
    chunks_used: int = 0
    failures: int = 0
    """Inferences that raised or returned non-finite values."""
    stale_dropped: int = 0
    """Chunks that arrived after they were no longer usable."""
    last_error: str | None = None


class ChunkPolicyRunner:
    """Call `step` once per control period with this period's observation; it returns the targets to send."""

    def __init__(self, infer: Infer, chunker: ActionChunker, n_obs_steps: int, initial_targets: np.ndarray,
                 stale_after_s: float = 1.0, synchronous: bool = False) -> None:
        """``initial_targets`` (A,) are held until the first chunk; ``synchronous`` runs inference inline (for
        simulations that run faster or slower than real time, where a worker's wall-clock latency is meaningless).
        """
        self.infer = infer
        self.chunker = chunker
        self.history: deque[dict[str, np.ndarray]] = deque(maxlen=n_obs_steps)
        self.last_target = np.array(initial_targets, dtype=float)
        self.stale_after_steps = stale_after_s / chunker.control_dt
        self.synchronous = synchronous
        self.status = RunnerStatus()
        self._executor = None if synchronous else ThreadPoolExecutor(max_workers=1, thread_name_prefix="dp-infer")
        self._step = 0
        self._plan = np.zeros((0, len(self.last_target)))
        self._plan_index = 0
        self._request: tuple[int, Future] | None = None
        self._pending: tuple[int, np.ndarray] | None = None

    def step(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        """Targets for this control step; ``observation`` maps keys (``observation.state``...) to this step's data."""
        k = self._step
        substeps = self.chunker.substeps
        if k % substeps == 0:
            observation = {key: np.array(value) for key, value in observation.items()}  # the caller may reuse arrays
            if not self.history:
                self.history.extend(observation for _ in range(self.history.maxlen))  # pad like the dataset
            self.history.append(observation)
        self._collect(k)
        remaining = len(self._plan) - self._plan_index
        if (self._request is None and self._pending is None and k % substeps == 0
                and remaining <= self.chunker.latency_drop * substeps):
            self._submit(k)
            self._collect(k)
        self._adopt(k)
        if self._plan_index < len(self._plan):
            self.last_target = self._plan[self._plan_index]
            self._plan_index += 1
            self.status.holding = False
        else:
            self.status.holding = True
        self._step += 1
        return self.last_target.copy()

    def close(self) -> None:
        """Stop the worker (an inference in progress is abandoned)."""
        if self._executor is not None:
            self._executor.shutdown(wait=False, cancel_futures=True)

    def _submit(self, k: int) -> None:
        history = {key: np.stack([obs[key] for obs in self.history]) for key in self.history[-1]}
        future: Future
        if self._executor is None:
            future = Future()
            try:
                future.set_result(self.infer(history))
            except Exception as exc:  # a failed inference holds the targets; it must not stop the control loop
                future.set_exception(exc)
        else:
            future = self._executor.submit(self.infer, history)
        self._request = (k, future)

    def _collect(self, k: int) -> None:
        if self._request is None or not self._request[1].done():
            return
        request_step, future = self._request
        self._request = None
        try:
            chunk = np.asarray(future.result(), dtype=float)
            if not np.isfinite(chunk).all():
                raise ValueError("inference returned non-finite actions")
            if chunk.ndim != 2 or chunk.shape[1] != len(self.last_target):
                raise ValueError(f"inference returned a chunk of shape {chunk.shape}, expected (horizon, "
                                 f"{len(self.last_target)})")
            plan = self.chunker.plan(chunk)
        except Exception as exc:
            self.status.failures += 1
            self.status.last_error = f"{type(exc).__name__}: {exc}"
            return
        if k - request_step > self.stale_after_steps:
            self.status.stale_dropped += 1
            return
        self._pending = (request_step + self.chunker.latency_drop * self.chunker.substeps, plan)

    def _adopt(self, k: int) -> None:
        if self._pending is None or k < self._pending[0]:
            return
        start, plan = self._pending
        self._pending = None
        late = k - start
        if late >= len(plan):
            self.status.stale_dropped += 1
            return
        self._plan, self._plan_index = plan, late
        self.status.chunks_used += 1
