"""The persistent compilation cache of `rl train` (`toddlerbot.rl.compilation`) and the compile time the metrics keep
apart from training time. Cache tests run in fresh processes: JAX reads its cache settings once per process."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("brax")

from ppo_support import CFG, TargetEnv  # noqa: E402
from toddlerbot.errors import ToddlerbotError  # noqa: E402
from toddlerbot.metrics import Dashboards  # noqa: E402
from toddlerbot.rl import compilation, train  # noqa: E402
from toddlerbot.rl.config import EnvConfig, ImitationConfig  # noqa: E402

TESTS = Path(__file__).resolve().parent
SRC = TESTS.parent / "src"

TINY_RUN = """
import json, sys
from jax import monitoring
events = {}
monitoring.register_event_listener(
    lambda event, **kw: events.__setitem__(event, events.get(event, 0) + 1))
import jax
from toddlerbot.rl import compilation
mode, work = sys.argv[1:]
if mode == "any-time":  # the tiny task's programs compile in about a second: cache each of them
    compilation.MIN_COMPILE_SECONDS = 0.0
setting = compilation.use_compile_cache(mode != "no-cache")
clock = compilation.compile_clock()
if work == "epoch":
    from ppo_support import CFG, TargetEnv
    from toddlerbot.rl import train
    ppo = train.PPO(TargetEnv(), CFG)
    ts, env_state = ppo.initial_state(jax.random.PRNGKey(0)), ppo.reset(jax.random.PRNGKey(1))
    ppo.epoch(ts, env_state, jax.random.PRNGKey(2))
else:
    jax.jit(lambda x: x * 2.0 + 1.0)(1.0)
count = lambda name: events.get("/jax/compilation_cache/" + name, 0)
print(json.dumps({"folder": str(setting.folder) if setting.folder else None, "source": setting.source,
                  "requests": count("compile_requests_use_cache"), "hits": count("cache_hits"),
                  "misses": count("cache_misses"), "compile_s": clock.seconds(),
                  "config": {name: getattr(jax.config, name) for name in (
                      "jax_enable_compilation_cache", "jax_compilation_cache_max_size",
                      "jax_persistent_cache_min_compile_time_secs", "jax_persistent_cache_min_entry_size_bytes")}}))
"""


def _tiny_run(mode: str, work: str = "epoch", **env) -> dict:
    """One fresh process that compiles and runs one epoch of the tiny PPO task (``work`` "jit": one small program)
    with the cache on (``mode`` "default", or "any-time": every program written) or off ("no-cache"); what it
    reports."""
    variables = {k: v for k, v in os.environ.items() if not k.startswith(("JAX_", "TODDLERBOT_"))}
    variables["PYTHONPATH"] = os.pathsep.join([str(SRC), str(TESTS)])
    out = subprocess.run([sys.executable, "-c", TINY_RUN, mode, work], env={**variables, **env}, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.splitlines()[-1])


def _entries(folder: Path) -> list[Path]:
    return sorted(folder.glob("*-cache"))


def test_a_second_process_loads_every_program_from_the_cache(tmp_path):
    """Two processes compile the same tiny PPO run with one cache folder: the first compiles and writes each program,
    the second loads each of them and compiles none."""
    first = _tiny_run("any-time", TODDLERBOT_COMPILE_CACHE=str(tmp_path / "cache"))
    folder = tmp_path / "cache" / compilation.host_tag()
    assert first["folder"] == str(folder) and first["source"] == "TODDLERBOT_COMPILE_CACHE"
    written = _entries(folder)
    assert first["misses"] == len(written) >= 3  # the reset, the networks' initialisation, the epoch, ...
    assert first["hits"] + first["misses"] == first["requests"]  # a program met again in this process is a hit
    second = _tiny_run("any-time", TODDLERBOT_COMPILE_CACHE=str(tmp_path / "cache"))
    assert second["misses"] == 0 and second["hits"] == second["requests"] == first["requests"]
    assert _entries(folder) == written


def test_the_cache_settings_and_the_switch_to_turn_it_off(tmp_path):
    """The documented limits reach JAX; --no-compile-cache (``enabled`` False) or TODDLERBOT_COMPILE_CACHE=off asks
    the cache for nothing and writes nothing."""
    on = _tiny_run("default", "jit", TODDLERBOT_COMPILE_CACHE=str(tmp_path / "cache"))
    assert on["config"] == {"jax_enable_compilation_cache": True, "jax_compilation_cache_max_size": 2 * 1024**3,
                            "jax_persistent_cache_min_compile_time_secs": 1.0,
                            "jax_persistent_cache_min_entry_size_bytes": 0}
    assert on["requests"] >= 1
    for mode, env in (("no-cache", {"TODDLERBOT_COMPILE_CACHE": str(tmp_path / "off")}),
                      ("default", {"TODDLERBOT_COMPILE_CACHE": "off"})):
        off = _tiny_run(mode, "jit", **env)
        assert off["folder"] is None and off["requests"] == 0 and not off["config"]["jax_enable_compilation_cache"]
    assert not (tmp_path / "off").exists()


def test_cache_folder_by_variable_xdg_home_or_jax(tmp_path, monkeypatch):
    monkeypatch.delenv(compilation.CACHE_VARIABLE, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    tag = compilation.host_tag()
    assert compilation._setting(True, None) == compilation.CacheSetting(tmp_path / "xdg/toddlerbot/jax" / tag,
                                                                       "default")
    assert (tmp_path / "xdg/toddlerbot/jax" / tag).is_dir()
    monkeypatch.setenv(compilation.CACHE_VARIABLE, str(tmp_path / "mine"))
    assert compilation._setting(True, None).folder == tmp_path / "mine" / tag
    assert compilation._setting(True, str(tmp_path / "jax")) == compilation.CacheSetting(
        tmp_path / "jax", "JAX_COMPILATION_CACHE_DIR")  # JAX's own setting wins
    assert compilation._setting(False, str(tmp_path / "jax")).folder is None  # and is turned off by the switch
    monkeypatch.setenv(compilation.CACHE_VARIABLE, "Off")
    assert compilation._setting(True, None).describe() == "compilation cache: off (TODDLERBOT_COMPILE_CACHE=Off)"


def test_a_cache_folder_that_cannot_be_made_is_one_line(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv(compilation.CACHE_VARIABLE, str(blocker))
    with pytest.raises(ToddlerbotError) as err:
        compilation._setting(True, None)
    assert str(err.value).startswith(f"TODDLERBOT_COMPILE_CACHE={blocker}: cannot make the compilation cache's "
                                     "folder there") and "\n" not in str(err.value)
    monkeypatch.delenv(compilation.CACHE_VARIABLE)
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker))  # the default place: train on without a cache
    setting = compilation._setting(True, None)
    assert setting.folder is None and setting.source.startswith(f"off: {blocker}/toddlerbot/jax/")


def test_the_clock_counts_nested_and_overlapping_spans_once():
    clock = compilation.CompileClock()
    trace, lower, compile_ = compilation.COMPILE_EVENTS
    clock.listen(trace, 1.0, 2.0)  # an inner trace ends first
    clock.listen(trace, 0.5, 3.0)  # the outer one holds it
    clock.listen(lower, 3.0, 4.0)
    clock.listen(compile_, 5.0, 7.5)
    clock.listen(compile_, 7.0, 7.2)  # another thread's, inside the last
    clock.listen("/jax/other", 0.0, 100.0)
    assert clock.seconds() == pytest.approx(2.5 + 1.0 + 2.5)


class _RunnableTargetEnv(TargetEnv):
    """The tiny task as `train.train` runs an environment (a configuration to save, no action space to record)."""

    cfg = EnvConfig()

    def record_action_space(self, run_dir):
        pass


def test_metrics_keep_compile_time_apart_from_training_time(tmp_path):
    """The first epoch's record holds the compilation (the reset and the epoch's program); its ``epoch_seconds`` and
    ``sps`` are the training alone. The second epoch compiles nothing."""
    _, history = train.train(tmp_path / "run", EnvConfig(), CFG, env=_RunnableTargetEnv(), max_epochs=2,
                             imitation_cfg=ImitationConfig(iterations=0), dashboards=Dashboards(tensorboard=False))
    first, second = history
    assert first["compile_s"] > 0.2 and second["compile_s"] == 0.0  # not a single op compiled again
    assert first["epoch_seconds"] < 0.5 * first["compile_s"]  # one update of 16 envs: milliseconds
    assert first["walltime"] >= first["compile_s"] + first["epoch_seconds"]
    for record in history:
        assert record["sps"] == pytest.approx(CFG.env_steps_per_update / record["epoch_seconds"])
    logged = [json.loads(line) for line in (tmp_path / "run" / "metrics.jsonl").read_text().splitlines()]
    assert [r["compile_s"] for r in logged] == [first["compile_s"], second["compile_s"]]
