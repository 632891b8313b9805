"""PPO over several processes and machines with JAX's multi-process runtime (`jax.distributed`).

Each process of a run (one per machine, or one per GPU) runs ``rl train`` with the same options and its own process
id. `join` connects them before anything touches JAX's devices: from ``--coordinator HOST:PORT --num-processes N
--process-id K``, or from a launcher's environment that ``jax.distributed.initialize`` reads itself (a SLURM job
step of several tasks, ``srun``; Open MPI's ``mpirun``; ``JAX_COORDINATOR_ADDRESS`` in place of ``--coordinator``). Then
``jax.devices()`` holds the devices of every process, and the PPO epoch's ``pmap`` spans them all: each process
steps its share of the environments on its own devices, and gradients and normaliser statistics are averaged over
every device of every process (`toddlerbot.rl.train.PPO`). On the CPU, processes exchange them through gloo (JAX
0.9's default CPU collectives); on GPUs through NCCL.

Process 0 alone writes the run directory (configuration, checkpoints, metrics, dashboards); every process reads it
on ``--resume``, so it must be on a filesystem all of them see, and process 0's state is broadcast to the others.
"""

from __future__ import annotations

import os
import socket
import time
from dataclasses import dataclass

from toddlerbot.errors import ToddlerbotError

MAX_PORT = 65535
COORDINATOR_WAIT_S = 300.0
"""How long a process other than 0 waits for process 0's coordinator to answer (JAX's own wait; past it JAX
aborts the process with a stack trace, so `join` gives up first, in one line)."""


@dataclass(frozen=True)
class Processes:
    """How this process joins a run's processes (`join`): all None where the launcher's environment says."""

    coordinator: str | None = None
    """``HOST:PORT`` of process 0's coordinator service (`parse_coordinator`)."""
    num_processes: int | None = None
    process_id: int | None = None

    def __post_init__(self) -> None:
        if self.coordinator is not None:
            parse_coordinator(self.coordinator)
        if self.num_processes is not None and self.num_processes < 1:
            raise ToddlerbotError(f"--num-processes {self.num_processes}: expected at least 1")
        missing = [option for option, value in (("--coordinator", self.coordinator),
                                                ("--num-processes", self.num_processes),
                                                ("--process-id", self.process_id)) if value is None]
        if os.environ.get("JAX_COORDINATOR_ADDRESS"):  # JAX reads it in place of --coordinator
            missing = [option for option in missing if option != "--coordinator"]
        if self.given and missing and self.num_processes != 1 and launcher_process_count() is None:
            raise ToddlerbotError(f"{', '.join(missing)} missing: --coordinator HOST:PORT, --num-processes N and "
                                  "--process-id K go together (outside a launcher that sets them: SLURM's srun, "
                                  "Open MPI's mpirun)")
        if self.process_id is not None:
            count = self.num_processes or launcher_process_count()
            if count is not None and not 0 <= self.process_id < count:
                raise ToddlerbotError(f"--process-id {self.process_id}: expected 0 to {count - 1} for {count} "
                                      "processes")

    @property
    def given(self) -> bool:
        return any(value is not None for value in (self.coordinator, self.num_processes, self.process_id))

    def wanted(self) -> bool:
        """Whether this run has several processes: by the options, else by the launcher's environment."""
        if self.num_processes is not None:
            return self.num_processes > 1
        return (launcher_process_count() or 1) > 1


def parse_coordinator(text: str) -> tuple[str, int]:
    """(host, port) of ``HOST:PORT`` (an IPv6 host in brackets, ``[::1]:1234``), or one line naming the option."""
    host, colon, port = text.strip().rpartition(":")
    bracketed = host.startswith("[") and host.endswith("]")
    host = host[1:-1] if bracketed else host
    if not (colon and host and (bracketed or ":" not in host) and not any(c.isspace() for c in host)
            and port.isdigit() and 1 <= int(port) <= MAX_PORT):
        raise ToddlerbotError(f"--coordinator {text}: expected HOST:PORT (e.g. 10.0.0.1:1234 or node001:1234; a port "
                              f"in 1-{MAX_PORT}), the address of process 0")
    return host, int(port)


def launcher_process_count() -> int | None:
    """The number of processes a launcher started this one among, from the variables JAX's cluster detection reads
    (a SLURM job step: ``srun``; Open MPI: ``mpirun``); None outside one."""
    slurm = ("SLURM_JOB_ID", "SLURM_STEP_NODELIST", "SLURM_NTASKS", "SLURM_PROCID", "SLURM_LOCALID")
    if all(name in os.environ for name in slurm):
        return _count("SLURM_NTASKS")
    if "OMPI_MCA_orte_hnp_uri" in os.environ and "OMPI_COMM_WORLD_SIZE" in os.environ:
        return _count("OMPI_COMM_WORLD_SIZE")
    return None


def _count(name: str) -> int:
    value = os.environ[name]
    if not value.isdigit() or int(value) < 1:
        raise ToddlerbotError(f"{name}={value}: expected a number of processes")
    return int(value)


def join(processes: Processes) -> str | None:
    """Connect this process to the run's others (`Processes.wanted`), before anything touches JAX's devices;
    returns a line saying which process this is of how many, and how many devices they have together (None: a
    single process, nothing done). Process ``K > 0`` waits for the coordinator up to `COORDINATOR_WAIT_S`."""
    import jax

    if not processes.wanted():
        return None
    if processes.coordinator is not None and processes.process_id:  # process 0 starts the coordinator itself
        wait_for_coordinator(processes.coordinator, COORDINATOR_WAIT_S)
    if jax.config.jax_cpu_collectives_implementation is None:  # older JAX had no CPU collectives by default
        jax.config.update("jax_cpu_collectives_implementation", "gloo")
    try:
        jax.distributed.initialize(processes.coordinator, processes.num_processes, processes.process_id)
        devices = jax.devices()
    except (RuntimeError, ValueError, TypeError) as exc:  # JAX's own checks, and XLA's errors of a failed connection
        reason = " ".join(str(exc).split())[:300] or type(exc).__name__
        where = f"--coordinator {processes.coordinator}" if processes.coordinator else "jax.distributed"
        raise ToddlerbotError(f"{where}: could not join the run's processes ({reason})") from None
    coordinator = processes.coordinator or os.environ.get("JAX_COORDINATOR_ADDRESS") or "the launcher's"
    return (f"process {jax.process_index()} of {jax.process_count()} (coordinator {coordinator}): "
            f"{jax.local_device_count()} of the {len(devices)} {devices[0].platform} devices here")


def wait_for_coordinator(address: str, timeout_s: float) -> None:
    """Return once ``HOST:PORT`` accepts a connection; one line after ``timeout_s`` seconds without."""
    host, port = parse_coordinator(address)
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            with socket.create_connection((host, port), timeout=min(5.0, timeout_s)):
                return
        except OSError as exc:
            if time.monotonic() >= deadline:
                reason = " ".join(str(exc).split()) or type(exc).__name__
                raise ToddlerbotError(f"--coordinator {address}: nothing answered there in {timeout_s:.0f} s "
                                      f"({reason}); start process 0 on that machine with the same --coordinator, or "
                                      "check the address and the firewall") from None
            time.sleep(min(1.0, max(0.0, deadline - time.monotonic())))


def is_main() -> bool:
    """Whether this is process 0, the one that writes the run directory (always, in a single-process run)."""
    import jax

    return jax.process_index() == 0


def several() -> bool:
    import jax

    return jax.process_count() > 1


def first_local_device() -> int:
    """The position of this process's first device among all processes' devices (`jax.devices()` order): where its
    share of a global batch of per-device items starts."""
    import jax

    return [device.process_index for device in jax.devices()].index(jax.process_index())


def from_main(tree):
    """Process 0's value of ``tree`` (arrays) on every process (unchanged in a single-process run): a resumed or
    warm-started state is the same everywhere even where a process read another copy of the file."""
    if not several():
        return tree
    from jax.experimental import multihost_utils

    return multihost_utils.broadcast_one_to_all(tree)


def agree(what: str, text: str) -> None:
    """Refuse in one line, on every process, a run whose processes were given different ``text`` (their
    configurations: other options would compile other programs, whose collectives never meet)."""
    if not several():
        return
    import hashlib

    import numpy as np
    from jax.experimental import multihost_utils

    digest = np.frombuffer(hashlib.sha256(text.encode()).digest(), np.uint8)
    digests = np.asarray(multihost_utils.process_allgather(digest))
    other = next((k for k, d in enumerate(digests) if not np.array_equal(d, digests[0])), None)
    if other is not None:
        raise ToddlerbotError(f"process {other}'s {what} differs from process 0's: give every process the same "
                              "options (and, with --resume, the same run)")


def decide(flag: bool) -> bool:
    """Process 0's ``flag`` on every process: a wall-time stop must stop all of them before the same epoch."""
    if not several():
        return flag
    import numpy as np

    return bool(from_main(np.asarray(flag, np.int32)))


def wait_for_main(name: str) -> None:
    """Block until every process got here (process 0 has written what the others read next)."""
    if several():
        from jax.experimental import multihost_utils

        multihost_utils.sync_global_devices(name)
