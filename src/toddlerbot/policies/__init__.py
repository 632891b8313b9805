"""Policies (observation + command -> motor targets) and their registry, which the CLI offers."""

from __future__ import annotations

import inspect
from collections.abc import Callable
from pathlib import Path

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.base import Action, Policy
from toddlerbot.registry import Registry
from toddlerbot.robot.interface import Robot

MAX_PREVIEW_TICKS = 2400
"""Longest ZMP preview walk-zmp plans with, ticks (its 1.2 s preview at 0.5 ms): a shorter control period would
make planning the gait itself the run (at 1 ns: 1.2e9 ticks, minutes of CPU and gigabytes)."""
POLICY_REGISTRY = Registry("policy", entry_point_group="toddlerbot.policies")
"""Every policy `make_policy` builds and `sim run`, `hw run` and `eval tracking` offer: the built-in ones, those of
installed packages (entry-point group ``toddlerbot.policies``) and those added with `register_policy`."""

__all__ = ["POLICY_REGISTRY", "Action", "Policy", "check_policy_options", "make_policy", "policy_names",
           "register_policy"]


def register_policy(name: str, factory: str | Callable[..., Policy] | None = None):
    """Offer a policy by `name`: `factory` is a `Policy` subclass or a function of the robot (also of ``motion``
    or ``weights`` if it names them) returning a policy, or ``"module:attribute"`` imported on first use. Without
    `factory`, a decorator. A name already registered is refused."""
    return POLICY_REGISTRY.register(name, factory)


def policy_names() -> tuple[str, ...]:
    """Every policy name `make_policy` accepts, the built-in ones first."""
    return POLICY_REGISTRY.names()


def make_policy(name: str, robot: Robot, motion: str | None = None, weights: str | Path | None = None,
                **options: object) -> Policy:
    """Build a registered policy by name; ``motion`` (a built-in name or a file) is required by ``replay``;
    ``weights`` is an exported RL policy for ``walk-rl`` (default: the shipped one); further ``options`` go to a
    factory that names them (``dp``: checkpoint, camera, threads, synchronous, task). A factory that does not name
    an option ignores it, as ``stand`` always has (the CLI refuses such an option first: `check_policy_options`)."""
    factory = POLICY_REGISTRY.get(name)
    options = {"motion": motion, "weights": weights, **options}
    return factory(robot, **{k: v for k, v in options.items() if v is not None and _accepts(factory, k)})


def accepts_option(name: str, option: str) -> bool:
    """Whether the policy registered as `name` takes `option` (e.g. a ``camera`` a task scene can give it)."""
    return _accepts(POLICY_REGISTRY.get(name), option)


def check_policy_options(name: str, **given: object) -> None:
    """One line when an option given (not None) is one the policy's factory does not take, e.g. ``--weights`` for
    ``stand``: the CLI refuses it rather than ignore it."""
    factory = POLICY_REGISTRY.get(name)
    for option, value in given.items():
        if value is not None and not _accepts(factory, option):
            raise ToddlerbotError(f"--{option} is not an option of policy {name!r}")


def _accepts(factory: Callable, option: str) -> bool:
    """Whether `factory` takes `option` by keyword (its signature names it, or takes ``**kwargs``)."""
    parameters = inspect.signature(factory).parameters.values()
    return any(p.name == option or p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters)


def _replay(robot: Robot, motion: str | None = None) -> Policy:
    from toddlerbot.policies.motions import builtin_motions, load_motion
    from toddlerbot.policies.replay import ReplayPolicy

    if motion is None:
        raise ToddlerbotError(f"policy 'replay' needs --motion ({', '.join(builtin_motions())} or a motion file)")
    return ReplayPolicy(robot, load_motion(motion, robot.description))


def _walk_zmp(robot: Robot) -> Policy:
    from toddlerbot.policies.walk_zmp import WalkZMPPolicy

    return WalkZMPPolicy(robot, _walk_config(robot.control_dt))


def _walk_rl(robot: Robot, weights: str | Path | None = None, symmetric: bool = True, stand: bool = True) -> Policy:
    from toddlerbot.policies.walk_rl import WalkRLPolicy

    return WalkRLPolicy(robot, weights, symmetric, stand)


_BUILT_IN = {"stand": "toddlerbot.policies.stand:StandPolicy", "replay": _replay, "walk-zmp": _walk_zmp,
             "walk-rl": _walk_rl, "dp": "toddlerbot.dp.live:dp_policy",
             "get-up": "toddlerbot.policies.get_up:GetUpPolicy", "track": "toddlerbot.policies.track:TrackPolicy"}
"""``dp`` (a diffusion-policy checkpoint, extra ``[dp]``) is built in the dp package, imported only when chosen."""
for _name, _factory in _BUILT_IN.items():
    POLICY_REGISTRY.register(_name, _factory)


def _walk_config(dt: float):
    """The gait configuration at control period `dt` (s), or one line saying why walk-zmp cannot plan at it."""
    from toddlerbot.locomotion.config import WalkConfig

    cannot = f"walk-zmp cannot plan at a control period of {dt:g} s"
    try:
        config = WalkConfig(dt=dt)
    except ValueError as exc:
        raise ToddlerbotError(f"{cannot}: {exc}") from None
    if config.preview_ticks > MAX_PREVIEW_TICKS:
        raise ToddlerbotError(f"{cannot}: its {config.preview_time:g} s preview would be {config.preview_ticks} "
                              f"ticks (at most {MAX_PREVIEW_TICKS}); use a period of at least "
                              f"{config.preview_time / MAX_PREVIEW_TICKS:g} s")
    return config
