"""Compiled code next to MuJoCo: numba where it is installed, and MuJoCo's own ``mj_step`` as a C function.

The actuated plant calls ``mj_step`` every 1 ms physics substep with the actuator model in between. Run from
Python, that interleaving costs a third of ``mj_step`` again (numpy calls and the interpreter evicting MuJoCo's
caches); compiled with numba, the whole substep loop runs in machine code and calls the C ``mj_step`` directly.

* `compiled`: numba's ``njit`` (no GIL, cached on disk) when numba is installed (a dependency of the package);
  where it is missing (a Python it does not support yet) the very same Python runs interpreted, with the same
  results, only slower.
* `prune_stale_caches`: the disk cache keeps one folder per state of the sources; old ones are deleted.
* `compile_now`: compile (or load) before a time-critical loop, then keep numba's bookkeeping away from the
  garbage collector.
* `compilable`: lets compiled code call a plain function (the actuator model, written once for numpy and JAX),
  which stays an ordinary Python function for everyone else. The model is elementwise, and compiled code
  evaluates it motor by motor on floats (no array temporaries: a quarter of the time), so numba is taught the
  float forms of ``np.clip`` and ``np.where`` it lacks (numpy's semantics, signed zeros included).
* `address`, `doubles`, `ints`: an array's address, and in compiled code the float64 or int32 values at an address
  as an array, so that one compiled call can read and write the MuJoCo arrays of many robots (their addresses are
  fixed for the life of the model or data).
* `mj_step`: ``mj_step(model_address, data_address)`` in the MuJoCo library the ``mujoco`` package loaded.
  Unlike ``mujoco.mj_step`` it turns no MuJoCo error into a Python exception (no exception can pass through
  compiled code, and MuJoCo cannot go on after an error): a fatal MuJoCo error (which a compiled, well-sized model
  does not raise while stepping; an arena too small for the contacts does) ends the process as the command line
  ends on any error that stops a command, with one line naming MuJoCo's message and exit code 2
  (`fatal_mujoco_error`, MuJoCo's error handler for the calls made here; the bindings keep their own).
"""

from __future__ import annotations

import contextlib
import ctypes
import gc
import glob
import hashlib
import logging
import os
import shutil
import sys
import traceback
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

try:
    import numba
except ImportError:  # the same code runs interpreted
    numba = None

HAVE_NUMBA = numba is not None
"""Whether the substep loop runs compiled."""
log = logging.getLogger(__name__)


def _cache_folder() -> str:
    """Where numba keeps the compiled code: one folder per state of the sources it compiles from (numba checks
    only the file of the compiled function itself, and the actuator model lives in another)."""
    package = Path(__file__).resolve().parents[1]
    stamp = hashlib.sha256()
    for source in sorted([*(package / "actuation").glob("*.py"), *(package / "sim").glob("*.py")]):
        info = source.stat()
        stamp.update(f"{source.name} {info.st_size} {info.st_mtime_ns}".encode())
    root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return str(root / "toddlerbot" / "numba" / stamp.hexdigest()[:16])


KEPT_CACHES = 8
"""Cache folders of other source states kept beside the current one (other checkouts, recent versions)."""


def prune_stale_caches(current: str, keep: int = KEPT_CACHES) -> list[str]:
    """Delete all but the `keep` most recently used sibling folders of `current` (each edit of the sources makes a
    new one of about 1 MB); returns the deleted folders. A folder deleted under another process only costs it a
    compile."""
    root = Path(current).parent
    if not root.is_dir():
        return []
    others = sorted((p for p in root.iterdir() if p.is_dir() and p.name != Path(current).name),
                    key=lambda p: p.stat().st_mtime, reverse=True)
    stale = [str(p) for p in others[keep:]]
    for folder in stale:
        shutil.rmtree(folder, ignore_errors=True)
    return stale


_pruned = False


def compiled(function: Callable) -> Callable:
    """``function`` compiled by numba (releasing the GIL, so threads may step disjoint robots; cached on disk),
    else itself."""
    global _pruned
    if not HAVE_NUMBA:
        return function
    folder = _cache_folder()
    if not _pruned:
        prune_stale_caches(folder)
        _pruned = True
    previous, numba.config.CACHE_DIR = numba.config.CACHE_DIR, folder
    try:  # the cache's folder is chosen now, when the dispatcher is made
        return numba.njit(nogil=True, cache=True)(function)
    finally:
        numba.config.CACHE_DIR = previous


_settled = False


def compile_now(function: Callable, *args) -> None:
    """Call `compiled` ``function`` on ``args`` so that it is compiled, or loaded from the disk cache, now and not
    inside a time-critical loop. The first time in a process, and whenever that added code, garbage is collected
    and what is left frozen out of the collector's sight: numba's bookkeeping (about 100,000 objects) would
    otherwise make every full collection 3-6x longer (85-220 ms instead of 35), a pause that the HIL emulator's
    replies or a 50 Hz wall-clock loop cannot absorb."""
    global _settled
    before = len(getattr(function, "signatures", ()))
    try:
        function(*args)
    except Exception as exc:
        if not (HAVE_NUMBA and _from_numba_cache(exc)):
            raise
        folder = _cache_folder()
        aside = f"{folder}.corrupt-{os.getpid()}"
        with contextlib.suppress(FileNotFoundError):  # another process may have moved it first
            os.replace(folder, aside)  # kept for a look; pruned as a stale folder later
        log.warning("warning: the compiled-code cache %s could not be read (%s: an interrupted first compile or a full "
                    "disk?); moved it to %s and compiling afresh", folder, type(exc).__name__, aside)
        function(*args)
    if HAVE_NUMBA and (not _settled or len(function.signatures) > before):
        gc.collect()
        gc.freeze()
        _settled = True


def _from_numba_cache(exc: BaseException) -> bool:
    """Whether `exc` was raised while numba read its disk cache (truncated or foreign index or code files)."""
    frames = traceback.extract_tb(exc.__traceback__)
    return any(Path(frame.filename).match("*/numba/core/caching.py") for frame in frames)


def compilable(function: Callable) -> Callable:
    """Make ``function`` callable from `compiled` code; it stays the same Python function for other callers."""
    if HAVE_NUMBA:
        from numba.extending import register_jitable

        register_jitable(function)
    return function


if HAVE_NUMBA:
    from numba import types
    from numba.extending import overload

    def _floats(*values) -> bool:
        return all(isinstance(v, types.Float) for v in values)

    @overload(np.clip)
    def _clip_floats(a, a_min, a_max):
        if _floats(a, a_min, a_max):
            return lambda a, a_min, a_max: a_min if a < a_min else (a_max if a > a_max else a)
        return None

    @overload(np.where)
    def _where_floats(condition, x, y):
        if isinstance(condition, types.Boolean) and _floats(x, y):
            return lambda condition, x, y: x if condition else y
        return None


def address(array: np.ndarray) -> int:
    """Where a C-contiguous array's data starts: compiled code reads and writes MuJoCo's arrays there (a model's or
    data's arrays live, at the same address, as long as the model or data)."""
    if not array.flags.c_contiguous:
        raise ValueError("expected a C-contiguous array")
    return int(array.__array_interface__["data"][0])


if HAVE_NUMBA:
    from numba.extending import intrinsic, register_jitable

    def _pointer_to(element):
        @intrinsic
        def pointer(typingctx, at):
            if not isinstance(at, types.Integer):
                return None

            def codegen(context, builder, signature, args):
                return builder.inttoptr(args[0], context.get_value_type(signature.return_type))
            return types.CPointer(element)(at), codegen
        return pointer

    _double_pointer = _pointer_to(types.float64)
    _int_pointer = _pointer_to(types.int32)

    @register_jitable
    def doubles(at: int, n: int) -> np.ndarray:
        """The ``n`` float64 values at address ``at`` as an array (no copy). Compiled code only."""
        return numba.carray(_double_pointer(at), n)

    @register_jitable
    def ints(at: int, n: int) -> np.ndarray:
        """The ``n`` int32 values at address ``at`` as an array (no copy). Compiled code only."""
        return numba.carray(_int_pointer(at), n)
else:
    def doubles(at: int, n: int) -> np.ndarray:
        """The ``n`` float64 values at address ``at`` as an array (no copy)."""
        return np.ctypeslib.as_array((ctypes.c_double * int(n)).from_address(int(at)))

    def ints(at: int, n: int) -> np.ndarray:
        """The ``n`` int32 values at address ``at`` as an array (no copy)."""
        return np.ctypeslib.as_array((ctypes.c_int32 * int(n)).from_address(int(at)))


def _mujoco_library_path() -> str:
    """The MuJoCo shared library shipped inside the ``mujoco`` package (the one its bindings already loaded)."""
    folder = os.path.dirname(mujoco.__file__)
    for pattern in ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll"):
        found = sorted(glob.glob(os.path.join(folder, pattern)))
        if found:
            return found[0]
    raise ImportError(f"no MuJoCo shared library (libmujoco.so*, libmujoco*.dylib or mujoco.dll) in {folder}")


FATAL_EXIT_CODE = 2
"""Exit code of a process that MuJoCo stopped (the command line's for an error that stopped a command)."""


@ctypes.CFUNCTYPE(None, ctypes.c_char_p)
def fatal_mujoco_error(message: bytes) -> None:
    """MuJoCo's error handler outside its Python bindings (which install their own around each call): one line on
    stderr, then the process ends with `FATAL_EXIT_CODE` (MuJoCo's default would exit with 1, the command line's
    code for a run that failed its own check, such as a fall)."""
    lines = [line.strip() for line in message.decode("utf-8", "replace").splitlines() if line.strip()]
    sys.stderr.write(f"error: MuJoCo stopped the simulation: {'; '.join(lines)}\n")
    sys.stderr.flush()
    os._exit(FATAL_EXIT_CODE)


def _mj_step() -> Callable[[int, int], None]:
    """``mj_step(model_address, data_address)``: a symbol numba links to (so compiled code can be cached), or a
    ctypes function for interpreted code. Addresses are passed as integers, as pointers are. Installs
    `fatal_mujoco_error` as the library's error handler."""
    path = _mujoco_library_path()
    library = ctypes.CDLL(path)  # the library the bindings loaded: dlopen returns the same one
    ctypes.c_void_p.in_dll(library, "mju_user_error").value = ctypes.cast(fatal_mujoco_error, ctypes.c_void_p).value
    if HAVE_NUMBA:
        import llvmlite.binding

        llvmlite.binding.load_library_permanently(path)
        return numba.types.ExternalFunction("mj_step", numba.types.void(numba.types.intp, numba.types.intp))
    step = library.mj_step
    step.argtypes, step.restype = [ctypes.c_ssize_t, ctypes.c_ssize_t], None
    return step


mj_step = _mj_step()
