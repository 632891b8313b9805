"""What every registered RL environment is (`toddlerbot.rl.environments`): a Brax `Env` whose class carries its
whole bundle, so that `rl train --env NAME` trains it on either physics backend without knowing which it is.

The bundle: its name, its configuration class (`EnvConfig` or a subclass of it) and default configuration, its
reward terms with their weights beside them (`rewards.RewardTerms`), its resets (``reset``) and terminations
(`terminated`), the per-step metrics it reports besides its reward terms, and its default PPO settings by physics
backend (`Recipe`). Physics is built from the configuration once for all environments (`make_physics`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import ClassVar

import jax
import mujoco
import numpy as np
from brax.envs.base import Env

from toddlerbot.errors import ToddlerbotError
from toddlerbot.rl import randomization
from toddlerbot.rl.config import EnvConfig, Recipe
from toddlerbot.rl.physics import BACKENDS, Addresses, Frame
from toddlerbot.rl.rewards import RewardTerms
from toddlerbot.robot.description import RobotDescription


def training_description(cfg: EnvConfig) -> RobotDescription:
    """The robot an env configuration trains: the packaged spec with its variant and fitted motor parameters."""
    return RobotDescription.load(variant=cfg.variant, motor_params=cfg.motor_params)


def resolve_backend(name: str) -> str:
    """``auto`` -> ``mjx`` when JAX's default device is a GPU, else ``cpu``."""
    if name != "auto":
        return name
    return "mjx" if jax.default_backend() == "gpu" else "cpu"


class RLEnvironment(Env):
    """A registered environment. Subclasses set the class attributes and implement Brax's ``reset``/``step``,
    ending an episode where `terminated` says so."""

    name: ClassVar[str]
    """The name it is registered under (`rl train --env NAME`, a run's config.json)."""
    config_class: ClassVar[type[EnvConfig]] = EnvConfig
    reward_terms: ClassVar[RewardTerms]
    """Its reward terms, each beside its default weight."""
    recipes: ClassVar[Mapping[str, Recipe]]
    """Default PPO and warm-start settings for ``cpu``, ``mjx`` and ``smoke`` (`recipe`)."""
    step_metrics: ClassVar[tuple[str, ...]] = ()
    """Per-step metrics besides the reward terms, averaged over finished episodes in PPO's epoch records."""
    runtime_policy: ClassVar[str | None] = None
    """The registered runtime policy that plays its exports (`rl export`, then `sim run --policy NAME --weights
    FILE`); None: its runs are not exported."""
    curves: ClassVar[tuple[tuple[str, str], ...]] = (
        ("episode_reward", "episode return"), ("episode_length", "episode length (steps)"),
        ("fall_rate", "episode ends per env step"))
    """The (epoch-record key, title) panels of its runs' ``training_curve.png`` (`rl.plot`): PPO's own records here;
    an environment adds its ``step_metrics``."""

    cfg: EnvConfig
    mj_model: mujoco.MjModel
    """The training model (`toddlerbot.rl.model.training_model`)."""
    n_motors: int

    @classmethod
    def default_config(cls, smoke: bool = False) -> EnvConfig:
        """The configuration of a new run (``smoke``: of the tiny test run)."""
        return cls.config_class()

    @classmethod
    def write_export(cls, out: Path, arrays: dict[str, np.ndarray], cfg: EnvConfig, meta: dict,
                     description: RobotDescription, action_space: dict[str, np.ndarray] | None) -> Path:
        """Write (atomically) the exported policy file of a run: the actor's ``arrays`` (`rl.export.policy_arrays`),
        the common metadata ``meta`` and what `runtime_policy` needs besides (from the run's ``action_space``
        record, `record_action_space`)."""
        raise ToddlerbotError(f"the {cls.name!r} environment has no runtime policy: its runs are not exported")

    @classmethod
    def shipped_export(cls, cfg: EnvConfig) -> Path:
        """Where `rl export --ship` puts a run's policy in the package (the file its runtime policy loads by
        default)."""
        raise ToddlerbotError(f"the {cls.name!r} environment ships no policy")

    @classmethod
    def recipe(cls, backend: str, smoke: bool = False) -> Recipe:
        """The default PPO and warm-start settings on a resolved physics backend (``smoke``: the tiny run's)."""
        return cls.recipes["smoke" if smoke else backend]

    @classmethod
    def resolved_config(cls, cfg: EnvConfig) -> EnvConfig:
        """``cfg`` with its physics backend and reward weights resolved (what a run saves); a configuration of
        another environment, or of another class, is refused."""
        if cfg.environment != cls.name or type(cfg) is not cls.config_class:
            raise ValueError(f"a {type(cfg).__name__} of environment {cfg.environment!r}: the {cls.name!r} "
                             f"environment takes a {cls.config_class.__name__} of environment {cls.name!r}")
        weights = cls.reward_terms.weights(cfg.reward.weights)
        return replace(cfg, backend=resolve_backend(cfg.backend), reward=replace(cfg.reward, weights=weights))

    @staticmethod
    def make_physics(model: mujoco.MjModel, addresses: Addresses, cfg: EnvConfig):
        """The configuration's physics backend (`toddlerbot.rl.physics`) for the training model."""
        physics = BACKENDS[cfg.backend]
        if cfg.backend == "cpu":
            return physics(model, addresses, cfg.n_substeps, cfg.cpu_threads)
        return physics(model, addresses, cfg.n_substeps)

    def draw_randomization(self, key: jax.Array) -> randomization.DRParams:
        """An episode's domain randomisation (`toddlerbot.rl.randomization`): drawn with ``key`` when the
        configuration randomises, else the nominal model."""
        m, cfg = self.mj_model, self.cfg
        if cfg.randomize:
            return randomization.sample(key, cfg.randomization, m.nv, m.nbody, self.n_motors)
        return randomization.nominal(m.nv, m.nbody, self.n_motors)

    def terminated(self, frame: Frame, *reference: jax.Array) -> jax.Array:
        """Whether the episode ends after the step that reached ``frame`` (bool scalar); ``reference``: what an
        environment compares the frame with, if anything (``track``: the reference's row it should have reached)."""
        raise NotImplementedError

    def record_action_space(self, run_dir: Path) -> None:
        """Write into a new run's folder what its exported policy needs to turn actions into motor targets."""
        raise NotImplementedError

    @property
    def backend(self) -> str:
        return self.cfg.backend
