"""What compiling the training programs costs, and JAX's persistent compilation cache that saves it.

`rl train` compiles the PPO epoch (and the environments' reset, the warm start's programs) before it trains. With the
cache on (`use_compile_cache`), XLA's output is kept on disk, so a second run or a resume of the same configuration
loads it instead of compiling again. It lives in ``$XDG_CACHE_HOME/toddlerbot/jax/<CPU>`` (default
``~/.cache/toddlerbot/jax/<CPU>``, one folder per host CPU: `host_tag`) or in ``<CPU>`` of the folder
``TODDLERBOT_COMPILE_CACHE`` names; ``TODDLERBOT_COMPILE_CACHE=off`` or ``rl train --no-compile-cache`` turns it
off. Where JAX's own ``JAX_COMPILATION_CACHE_DIR`` is set, that folder and JAX's own settings are used. Programs
that call back into Python (the CPU physics backend's ``pure_callback``) are compiled every time: JAX writes no
cache entry for them.

`compile_clock` measures the seconds JAX spends compiling (tracing, lowering, and XLA's compile or its load from the
cache), so that a run's metrics keep compile time apart from training time.
"""

from __future__ import annotations

import hashlib
import os
import platform
import threading
from dataclasses import dataclass
from pathlib import Path

from toddlerbot.errors import ToddlerbotError

CACHE_VARIABLE = "TODDLERBOT_COMPILE_CACHE"
"""Environment variable: the cache's folder, or ``off`` (also ``0``, ``false``, ``no``) for no cache."""
OFF_VALUES = ("off", "0", "false", "no")

MAX_CACHE_BYTES = 2 * 1024**3
"""The cache's size limit (JAX's ``jax_compilation_cache_max_size``): least recently used entries are deleted
beyond it."""
MIN_COMPILE_SECONDS = 1.0
"""Programs that compile faster are not written (``jax_persistent_cache_min_compile_time_secs``)."""
MIN_ENTRY_BYTES = 0
"""No size floor: a small program that is slow to compile is worth keeping
(``jax_persistent_cache_min_entry_size_bytes``)."""


@dataclass(frozen=True)
class CacheSetting:
    """Where compiled programs are kept (None: nowhere) and why: ``default``, ``TODDLERBOT_COMPILE_CACHE``,
    ``JAX_COMPILATION_CACHE_DIR``, or ``off`` and the reason."""

    folder: Path | None
    source: str

    def describe(self) -> str:
        return f"compilation cache: {self.source}" if self.folder is None else \
            f"compilation cache: {self.folder} ({self.source})"


def default_cache_folder() -> Path:
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "toddlerbot" / "jax"


def host_tag() -> str:
    """This machine's CPU, as a folder name: XLA's CPU programs use the instructions of the CPU that compiled them
    and its loader does not refuse another CPU's, so machines sharing a home folder (a cluster) keep one cache
    each."""
    identity = platform.processor()
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
        identity = "\n".join(next((line for line in lines if line.startswith(key)), "")
                             for key in ("model name", "flags"))
    except OSError:
        pass
    return f"{platform.machine()}-{hashlib.sha256(identity.encode()).hexdigest()[:12]}"


def use_compile_cache(enabled: bool = True) -> CacheSetting:
    """Turn JAX's persistent compilation cache on (where `CacheSetting` says) or off, for everything this process
    compiles from now on. Call it before the training compiles anything."""
    import jax
    from jax.experimental.compilation_cache import compilation_cache

    setting = _setting(enabled, os.environ.get("JAX_COMPILATION_CACHE_DIR"))  # JAX read it when imported
    if setting.source != "JAX_COMPILATION_CACHE_DIR":
        jax.config.update("jax_enable_compilation_cache", setting.folder is not None)
    if setting.folder is not None and setting.source != "JAX_COMPILATION_CACHE_DIR":
        jax.config.update("jax_compilation_cache_dir", str(setting.folder))
        jax.config.update("jax_compilation_cache_max_size", MAX_CACHE_BYTES)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_SECONDS)
        jax.config.update("jax_persistent_cache_min_entry_size_bytes", MIN_ENTRY_BYTES)
    compilation_cache.reset_cache()  # JAX reads these settings when it first compiles; make it read them again
    return setting


def _setting(enabled: bool, jax_folder: str | None) -> CacheSetting:
    """The cache's folder, made if new; one line where ``TODDLERBOT_COMPILE_CACHE`` names one that cannot be."""
    value = os.environ.get(CACHE_VARIABLE, "").strip()
    if not enabled:
        return CacheSetting(None, "off")
    if value.lower() in OFF_VALUES:
        return CacheSetting(None, f"off ({CACHE_VARIABLE}={value})")
    if jax_folder:
        return CacheSetting(Path(jax_folder), "JAX_COMPILATION_CACHE_DIR")
    root, source = (Path(value).expanduser(), CACHE_VARIABLE) if value else (default_cache_folder(), "default")
    folder = root / host_tag()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        if source == CACHE_VARIABLE:
            raise ToddlerbotError(f"{CACHE_VARIABLE}={value}: cannot make the compilation cache's folder there "
                                  f"({exc.strerror or exc}); name a writable folder, or 'off'") from None
        return CacheSetting(None, f"off: {folder} cannot be made ({exc.strerror or exc})")
    return CacheSetting(folder, source)


COMPILE_EVENTS = ("/jax/core/compile/jaxpr_trace_duration", "/jax/core/compile/jaxpr_to_mlir_module_duration",
                  "/jax/core/compile/backend_compile_duration")
"""JAX's events of a compilation: tracing, lowering, XLA's compile (or the load of its result from the cache)."""


class CompileClock:
    """Seconds this process has spent compiling since the clock started listening: the union of JAX's compile
    events' time spans (a trace nested in another's counts once). Read it before and after a call: the difference
    is that call's compile time."""

    def __init__(self) -> None:
        self._spans: list[list[float]] = []  # disjoint, in time order
        self._lock = threading.Lock()

    def listen(self, event: str, start: float, end: float, **_) -> None:
        if event not in COMPILE_EVENTS:
            return
        with self._lock:  # spans arrive as they end: an earlier one overlapping this one is at the tail
            while self._spans and self._spans[-1][1] >= start:
                earlier = self._spans.pop()
                start, end = min(start, earlier[0]), max(end, earlier[1])
            self._spans.append([start, end])

    def seconds(self) -> float:
        with self._lock:
            return sum(end - start for start, end in self._spans)


_clock: CompileClock | None = None


def compile_clock() -> CompileClock:
    """The process's compile clock, listening from its first call on."""
    global _clock
    if _clock is None:
        from jax import monitoring

        _clock = CompileClock()
        monitoring.register_event_time_span_listener(_clock.listen)
    return _clock
