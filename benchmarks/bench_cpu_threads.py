"""Where the CPU backend's time goes, per thread (issue 45: "show that no thread waits on the GIL"): the walking
environment's jitted, vmapped step on the CPU physics backend, every host call timed on every thread it touches.

Each control step is one `jax.pure_callback` into `CPUPhysics._host_step` on the calling thread, which splits the
batch into one chunk per worker thread (`mujoco_*`); each chunk gathers its envs' state and randomised model
fields into arrays (Python, holding the GIL, a few numpy calls per chunk), makes one call into compiled code
(`toddlerbot.sim.actuated.step_batch`'s `_batch`: numba and MuJoCo's C, without the GIL) that writes them into each
env's MuJoCo model and data, runs its substeps and copies the results out, then reads each env's contacts
(Python). Timed here, per segment, in wall time and in the thread's own CPU time (`time.thread_time`): a thread
that holds no GIL-free work and whose wall time exceeds its CPU time was waiting, for the GIL or for a core.
Printed: the share of each kind of work, the waits, and what that serial share allows on more cores (Amdahl);
drawn: the threads' timeline of a few steps.

    PYTHONPATH=src python benchmarks/bench_cpu_threads.py [--envs 256] [--steps 30] [--threads 0]
                                                          [--out docs/figures/rl_cpu_threads.png]

Run it on an otherwise idle machine: another process taking a core shows up as waiting.
"""

from __future__ import annotations

import argparse
import os
import platform
import threading
import time
from collections import defaultdict
from dataclasses import dataclass, replace


@dataclass(frozen=True)
class Segment:
    thread: str
    kind: str
    """``host`` (the callback on the calling thread), ``chunk`` (one worker's share) or ``physics`` (the chunk's
    compiled step, without the GIL)."""
    start: float
    end: float
    cpu: float
    """The thread's CPU time spent in it, s."""


class Recorder:
    def __init__(self) -> None:
        self.segments: list[Segment] = []
        self.on = False
        self._lock = threading.Lock()

    def timed(self, kind: str, function):
        def wrapper(*args, **kwargs):
            if not self.on:
                return function(*args, **kwargs)
            t0, c0 = time.perf_counter(), time.thread_time()
            try:
                return function(*args, **kwargs)
            finally:
                segment = Segment(threading.current_thread().name, kind, t0, time.perf_counter(),
                                  time.thread_time() - c0)
                with self._lock:
                    self.segments.append(segment)
        return wrapper


class TimedDispatcher:
    """The compiled batch step, timed; `step_batch` also reads its ``signatures``."""

    def __init__(self, dispatcher, recorder: Recorder) -> None:
        self.dispatcher = dispatcher
        self.signatures = getattr(dispatcher, "signatures", ())
        self._call = recorder.timed("physics", dispatcher)
        self.last_arguments: tuple | None = None

    def __call__(self, *args):
        self.last_arguments = args
        return self._call(*args)

    def dispatch_seconds(self, repeats: int = 2000) -> float:
        """One call's cost with no env to step: numba checking and unboxing the arguments, with the GIL held."""
        args = (*(x[:0] for x in self.last_arguments[:7]), *self.last_arguments[7:])
        t0 = time.thread_time()
        for _ in range(repeats):
            self.dispatcher(*args)
        return (time.thread_time() - t0) / repeats


def instrument(recorder: Recorder) -> TimedDispatcher:
    """Time the callback, the workers' chunks and the compiled loop (before the environment is traced: the jitted
    step keeps the functions it was traced with)."""
    from toddlerbot.rl import physics
    from toddlerbot.sim import actuated

    actuated._batch = TimedDispatcher(actuated._batch, recorder)
    physics.CPUPhysics._host_step = recorder.timed("host", physics.CPUPhysics._host_step)
    physics.CPUPhysics._step_chunk = recorder.timed("chunk", physics.CPUPhysics._step_chunk)
    return actuated._batch


def summarise(segments: list[Segment], steps: list[tuple[float, float]], threads: int, dispatch: float) -> dict:
    """Seconds of each kind of work over the recorded steps (summed over threads), and the waits; ``dispatch``: s
    of GIL-held argument handling per call of the compiled loop, moved from its time to the Python's."""
    by_kind = defaultdict(list)
    for s in segments:
        by_kind[s.kind].append(s)
    wall = sum(b - a for a, b in steps)
    host = sum(s.end - s.start for s in by_kind["host"])
    chunk_wall = sum(s.end - s.start for s in by_kind["chunk"])
    chunk_cpu = sum(s.cpu for s in by_kind["chunk"])
    dispatch_total = dispatch * len(by_kind["physics"])
    physics_wall = sum(s.end - s.start for s in by_kind["physics"]) - dispatch_total
    physics_cpu = sum(s.cpu for s in by_kind["physics"]) - dispatch_total
    # the calling thread inside the callback but outside its workers: splitting and joining the batch (GIL)
    pool_span = 0.0
    for h in by_kind["host"]:
        inside = [s for s in by_kind["chunk"] if h.start <= s.start and s.end <= h.end]
        if inside:
            pool_span += max(s.end for s in inside) - min(s.start for s in inside)
    return {
        "steps_wall": wall,
        "outside_callback": wall - host,
        "host_serial": host - pool_span,
        "chunk_python_wall": chunk_wall - physics_wall,
        "chunk_python_cpu": chunk_cpu - physics_cpu,
        "physics_wall": physics_wall,
        "physics_cpu": physics_cpu,
        "threads": threads,
        "dispatch": dispatch,
    }


def draw(segments: list[Segment], steps: list[tuple[float, float]], path: str, shown: int = 3) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t0, t1 = steps[0][0], steps[min(shown, len(steps)) - 1][1]
    window = [s for s in segments if s.start < t1 and s.end > t0]
    caller = "calling thread (XLA's)"  # XLA runs each callback on one of its own threads
    lane = {s.thread: caller if s.kind == "host" else s.thread for s in window}
    names = sorted(set(lane.values()), key=lambda n: (n != caller, n))
    fig, ax = plt.subplots(figsize=(11, 1.0 + 0.6 * len(names)))
    colours = {"host": "#bbbbbb", "chunk": "#e07b39", "physics": "#3a78b5"}
    for row, name in enumerate(names):
        for kind in ("host", "chunk", "physics"):
            bars = [((s.start - t0) * 1e3, (s.end - s.start) * 1e3) for s in window if lane[s.thread] == name
                    and s.kind == kind]
            if bars:
                ax.broken_barh(bars, (row - 0.35, 0.7), color=colours[kind])
    for a, _ in steps[:shown]:
        ax.axvspan((a - t0) * 1e3, (a - t0) * 1e3 + 0.05, color="k")
    ax.set_yticks(range(len(names)), names)
    ax.set_xlabel("ms")
    ax.set_title("CPU backend, one env step per black line: grey the callback on the calling thread (outside it: "
                 "JAX), orange a worker's Python (GIL), blue compiled physics (no GIL)", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--envs", type=int, default=256)
    parser.add_argument("--steps", type=int, default=30)
    parser.add_argument("--threads", type=int, default=0, help="worker threads (0: one per core)")
    parser.add_argument("--out", default=None, help="timeline figure (PNG)")
    args = parser.parse_args()

    import jax
    import jax.numpy as jnp

    from toddlerbot.rl.config import EnvConfig
    from toddlerbot.rl.reference import load_reference
    from toddlerbot.rl.walk_env import WalkEnv
    from toddlerbot.robot.description import RobotDescription

    recorder = Recorder()
    loop = instrument(recorder)
    description = RobotDescription.load()
    cfg = replace(EnvConfig(), backend="cpu", cpu_threads=args.threads)
    reference, _ = load_reference(description, cfg.command, cfg.ctrl_dt)
    env = WalkEnv(cfg, description, reference=reference)
    reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
    state = reset(jax.random.split(jax.random.PRNGKey(0), args.envs))
    action = jnp.zeros((args.envs, env.action_size))
    for _ in range(3):  # compile and warm up
        state = step(state, action)
    jax.block_until_ready(state.obs)
    recorder.on = True
    steps = []
    for _ in range(args.steps):
        t0 = time.perf_counter()
        state = step(state, action)
        jax.block_until_ready(state.obs)
        steps.append((t0, time.perf_counter()))
    recorder.on = False
    f = summarise(recorder.segments, steps, env.physics.threads, loop.dispatch_seconds())
    n = args.steps
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, {f['threads']} worker threads, "
          f"{args.envs} envs, {n} steps; load average {os.getloadavg()[0]:.1f}")
    print(f"env steps/s {args.envs * n / f['steps_wall']:.0f}; per step {1e3 * f['steps_wall'] / n:.2f} ms wall")
    rows = (("JAX outside the callback (calling thread)", f["outside_callback"], None),
            ("callback, calling thread: split/join the batch (GIL)", f["host_serial"], None),
            ("workers: Python (GIL), with the compiled step's call", f["chunk_python_wall"],
             f["chunk_python_cpu"]),
            ("workers: compiled physics (no GIL)", f["physics_wall"], f["physics_cpu"]))
    for label, wall, cpu in rows:
        extra = "" if cpu is None else f", CPU {1e3 * cpu / n:7.2f} ms, waiting {1e3 * (wall - cpu) / n:6.2f} ms"
        print(f"  {label:55s} wall {1e3 * wall / n:7.2f} ms{extra}")
    print(f"  (one call of the compiled step costs {1e6 * f['dispatch']:.1f} us of argument handling under the GIL; "
          "one call per worker and step)")
    serial = f["outside_callback"] + f["host_serial"] + f["chunk_python_cpu"]
    work = serial + f["physics_cpu"]
    share = serial / work
    print(f"serial (one thread at a time: JAX side, split/join, GIL-held Python) {100 * share:.1f} % of the CPU work; "
          "Amdahl's bound on the speed-up over one core: " + ", ".join(
              f"{cores} cores {1 / (share + (1 - share) / cores):.1f}x" for cores in (2, 8, 16)))
    if args.out:
        draw(recorder.segments, steps, args.out)
        print(f"timeline: {args.out}")


if __name__ == "__main__":
    main()
