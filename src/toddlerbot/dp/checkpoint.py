"""Checkpoints that rebuild their own network and resume training exactly.

One file, written with ``torch.save`` and read with ``weights_only=True``: a dict of tensors, numbers and strings
only (no pickled objects). ``config`` is the `DPConfig` as JSON, so `load_policy` needs nothing else; ``model``
and ``ema`` are state dicts (normaliser ranges included as buffers); ``optimizer``, ``step``, ``rng`` (torch's
global generator) and ``data_rng`` (the sampling generator) let `train` continue where it stopped.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import torch

from toddlerbot.dp.config import DPConfig
from toddlerbot.dp.ema import EMA
from toddlerbot.dp.policy import ACTION, STATE, DiffusionPolicy
from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_write
from toddlerbot.yaml_input import sized_file

FORMAT = "toddlerbot-dp/1"


class CheckpointError(ToddlerbotError):
    """A diffusion-policy checkpoint is missing, unreadable or inconsistent with its own config."""


@dataclass
class TrainingState:
    """Everything a run needs to continue: the network, its EMA copy, the optimiser and the random streams."""

    policy: DiffusionPolicy
    ema: EMA
    optimizer: torch.optim.Optimizer
    step: int = 0
    data_rng: torch.Generator = field(default_factory=torch.Generator)
    history: list[dict[str, float]] = field(default_factory=list)
    """Per-evaluation records: step, train_loss, val_loss, seconds."""


def make_optimizer(policy: DiffusionPolicy) -> torch.optim.Optimizer:
    cfg = policy.config
    return torch.optim.AdamW(policy.parameters(), lr=cfg.learning_rate, weight_decay=cfg.weight_decay)


def new_training_state(config: DPConfig, ranges: dict[str, tuple] | None = None,
                       device: str | torch.device = "cpu") -> TrainingState:
    """A fresh network (seeded by ``config.seed``) with its normalisers set from ``ranges`` (key -> (min, max),
    keys ``observation.state`` and ``action``), its EMA copy and optimiser, on ``device``."""
    torch.manual_seed(config.seed)
    policy = DiffusionPolicy(config)
    if ranges is not None:
        policy.state_norm.fit(*ranges[STATE])
        policy.action_norm.fit(*ranges[ACTION])
    policy.to(device)
    data_rng = torch.Generator().manual_seed(config.seed)
    return TrainingState(policy, EMA(policy, config.ema_decay), make_optimizer(policy), data_rng=data_rng)


def save_checkpoint(path: str | Path, state: TrainingState) -> Path:
    """Write the training state atomically (temporary file in the same folder, then rename)."""
    body = {
        "format": FORMAT,
        "config": state.policy.config.to_json(),
        "model": state.policy.state_dict(),
        "ema": state.ema.model.state_dict(),
        "ema_updates": state.ema.updates,
        "optimizer": state.optimizer.state_dict(),
        "step": state.step,
        "rng": torch.get_rng_state(),
        "data_rng": state.data_rng.get_state(),
        "history": json.dumps(state.history),
    }
    return atomic_write(path, lambda tmp: torch.save(body, tmp))


MAX_CHECKPOINT_BYTES = 4 << 30
"""Largest checkpoint read, bytes: the appendix's 300 M-parameter policy is 1.2 GB of float32 weights, 3.6 GB with
its Adam moments (the shipped ones are 6 MB)."""


def _read(path: Path) -> dict[str, Any]:
    if not path.is_file():
        raise CheckpointError(f"{path}: no such checkpoint file")
    sized_file(path, "diffusion-policy checkpoint", CheckpointError, MAX_CHECKPOINT_BYTES)
    try:
        body = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # truncated zip, pickled objects, not a torch file
        raise CheckpointError(f"{path}: not a weights-only torch checkpoint ({type(exc).__name__}: "
                              f"{str(exc).splitlines()[0] if str(exc) else ''})") from exc
    if not isinstance(body, dict) or body.get("format") != FORMAT:
        found = body.get("format") if isinstance(body, dict) else type(body).__name__
        raise CheckpointError(f"{path}: format {found!r}, expected {FORMAT!r}")
    return body


def _network(path: Path, body: dict[str, Any], key: str) -> DiffusionPolicy:
    return _weights(path, body, key, _config(path, body, None))


def _weights(path: Path, body: dict[str, Any], key: str, config: DPConfig) -> DiffusionPolicy:
    policy = DiffusionPolicy(config)
    try:
        policy.load_state_dict(body[key])
    except (RuntimeError, KeyError) as exc:
        raise CheckpointError(f"{path}: {key} weights do not fit the config ({str(exc).splitlines()[0]})") from exc
    return policy


def load_policy(path: str | Path, use_ema: bool = True, binary_actions: tuple[str, ...] | None = None
                ) -> DiffusionPolicy:
    """The network of a checkpoint, in eval mode: the EMA weights unless ``use_ema`` is False; ``binary_actions``
    (names) replaces the config's (`DPConfig.binary_actions`: how the sampled actions are read, not the weights)."""
    path = Path(path)
    body = _read(path)
    return _weights(path, body, "ema" if use_ema else "model", _config(path, body, binary_actions)).eval()


def _config(path: Path, body: dict[str, Any], binary_actions: tuple[str, ...] | None) -> DPConfig:
    config = DPConfig.from_json(body["config"], source=f"{path} config")
    return config if binary_actions is None else replace(config, binary_actions=tuple(binary_actions))


def export_policy(checkpoint: str | Path, out: str | Path, binary_actions: tuple[str, ...] | None = None) -> Path:
    """Write only what inference needs (config, EMA weights with the normaliser ranges, step, history): the file
    to ship, with ``binary_actions`` in its config if given (as `load_policy`). `load_policy` and
    `checkpoint_summary` read it; it cannot resume training."""
    checkpoint = Path(checkpoint)
    body = _read(checkpoint)
    config = _config(checkpoint, body, binary_actions)
    _weights(checkpoint, body, "ema", config)  # the weights fit the config
    policy_only = {key: body[key] for key in ("format", "ema", "step", "history")} | {"config": config.to_json()}
    return atomic_write(out, lambda tmp: torch.save(policy_only, tmp))


def load_training_state(path: str | Path, device: str | torch.device = "cpu") -> TrainingState:
    """Everything `save_checkpoint` wrote, ready to continue training on ``device``; restores torch's global (CPU)
    RNG too."""
    path = Path(path)
    body = _read(path)
    if "optimizer" not in body:
        raise CheckpointError(f"{path}: an exported policy (weights only) cannot resume training; resume from the "
                              "run's checkpoint.pt")
    policy = _network(path, body, "model").to(device)
    ema = EMA(policy, policy.config.ema_decay)
    ema.model.load_state_dict(body["ema"])
    ema.updates = int(body["ema_updates"])
    optimizer = make_optimizer(policy)
    optimizer.load_state_dict(body["optimizer"])
    data_rng = torch.Generator()
    data_rng.set_state(body["data_rng"])
    torch.set_rng_state(body["rng"])
    return TrainingState(policy, ema, optimizer, int(body["step"]), data_rng, json.loads(body["history"]))


def checkpoint_summary(path: str | Path) -> dict[str, Any]:
    """What a checkpoint holds: training step, parameter count, the last losses and the whole config."""
    path = Path(path)
    body = _read(path)
    policy = _network(path, body, "ema")
    history = json.loads(body["history"])
    return {
        "checkpoint": str(path),
        "step": int(body["step"]),
        "parameters": sum(p.numel() for p in policy.parameters()),
        "last": history[-1] if history else None,
        "config": json.loads(body["config"]),
    }
