"""ONNX export of a diffusion policy's per-inference networks (`toddlerbot dp export --format onnx`).

Two graphs, written with ``torch.onnx.export`` (the TorchScript exporter: torch 2.13's default, the
``torch.export`` one, needs the separate ``onnxscript`` package) and checked against torch on random inputs:

* ``observation_encoder.onnx``: ``state`` (B, n_obs, state_dim) float32 in dataset units and, with an image
  encoder, ``images`` (B, n_obs, 3, H, W) uint8 -> ``cond`` (B, cond_dim): `DiffusionPolicy.condition` at
  inference (state normalisation, uint8 -> [0, 1], centre crop, encoder), run once per inference;
* ``noise_unet.onnx``: ``sample`` (B, horizon, action_dim), ``timestep`` (B,) int64, ``cond`` -> ``output``
  (B, horizon, action_dim): the U-Net's prediction (noise or clean sample, ``config.prediction``), run once per
  denoising step.

The sampler (DDPM/DDIM update, `scheduler.NoiseSchedule`) and the action un-normalisation stay outside the graphs;
each file's ``metadata_props`` carry what they need: the `DPConfig` JSON (``toddlerbot.dp_config``) and the action
range (``toddlerbot.action_centre``, ``toddlerbot.action_half_range``, JSON lists).
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import torch
from torch import nn

from toddlerbot.dp.policy import IMAGE, STATE, DiffusionPolicy
from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_write

OPSET = 17
TOLERANCE = 1e-5
"""Largest output difference between onnxruntime and torch accepted at export. Measured (float32 convolutions and
GroupNorm summed in another order): at most 2.6e-6 for the tiny, small (shipped pick) and appendix-size networks
(docs/rl.md, "Export and inference")."""
ENCODER_FILE, UNET_FILE = "observation_encoder.onnx", "noise_unet.onnx"
FORMATS = ("pt", "onnx")


class ObservationEncoder(nn.Module):
    """`DiffusionPolicy.condition` in eval mode as a module of plain tensors."""

    def __init__(self, policy: DiffusionPolicy) -> None:
        super().__init__()
        self.policy = policy
        self.eval()  # the exporter restores the wrapper's mode on all children afterwards: keep it eval (centre crop)

    def forward(self, state: torch.Tensor, images: torch.Tensor | None = None) -> torch.Tensor:
        batch = {STATE: state} if images is None else {STATE: state, IMAGE: images}
        return self.policy.condition(batch)


class NoiseUnet(nn.Module):
    """The conditional U-Net: (noisy sample, integer step, condition) -> prediction."""

    def __init__(self, policy: DiffusionPolicy) -> None:
        super().__init__()
        self.unet = policy.unet
        self.eval()

    def forward(self, sample: torch.Tensor, timestep: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        return self.unet(sample, timestep, cond)


def example_inputs(policy: DiffusionPolicy, batch: int = 2, seed: int = 0) -> dict[str, dict[str, torch.Tensor]]:
    """Random inputs of both graphs: states inside and beyond the normaliser's range, uint8 images, samples from
    N(0, 1), steps across the training schedule, and the encoder's condition of those observations."""
    cfg = policy.config
    gen = torch.Generator().manual_seed(seed)
    centre, half = policy.state_norm.centre, policy.state_norm.half_range
    state = centre + half * (2.5 * torch.rand((batch, cfg.n_obs_steps, cfg.state_dim), generator=gen) - 1.25)
    encoder = {"state": state.float()}
    if cfg.uses_images:
        encoder["images"] = torch.randint(0, 256, (batch, cfg.n_obs_steps, 3, cfg.image_size, cfg.image_size),
                                          generator=gen, dtype=torch.uint8)
    with torch.no_grad():
        cond = ObservationEncoder(policy)(**encoder)
    unet = {"sample": torch.randn((batch, cfg.horizon, cfg.action_dim), generator=gen),
            "timestep": torch.randint(0, cfg.train_timesteps, (batch,), generator=gen, dtype=torch.int64),
            "cond": cond}
    return {ENCODER_FILE: encoder, UNET_FILE: unet}


def _metadata(policy: DiffusionPolicy, role: str) -> dict[str, str]:
    return {"toddlerbot.role": role, "toddlerbot.dp_config": policy.config.to_json(),
            "toddlerbot.action_centre": json.dumps(policy.action_norm.centre.tolist()),
            "toddlerbot.action_half_range": json.dumps(policy.action_norm.half_range.tolist())}


def _export(module: nn.Module, inputs: dict[str, torch.Tensor], output: str, path: Path, metadata: dict[str, str],
            doc: str) -> None:
    import onnx

    names = list(inputs)
    dynamic = {name: {0: "batch"} for name in [*names, output]}

    def write(tmp: Path) -> None:
        with warnings.catch_warnings():  # the TorchScript exporter's deprecation and tracer notes
            warnings.simplefilter("ignore")
            torch.onnx.export(module, tuple(inputs.values()), str(tmp), input_names=names, output_names=[output],
                              dynamic_axes=dynamic, opset_version=OPSET, dynamo=False)
        model = onnx.load(str(tmp))
        onnx.helper.set_model_props(model, metadata)
        model.doc_string = doc
        onnx.checker.check_model(model)
        onnx.save(model, str(tmp))

    atomic_write(path, write)


def session(path: Path):
    """An onnxruntime session of an exported graph on the CPU, one thread (as the robot runs it)."""
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.intra_op_num_threads, options.inter_op_num_threads = 1, 1
    options.log_severity_level = 3
    return ort.InferenceSession(str(path), sess_options=options, providers=["CPUExecutionProvider"])


def verify(policy: DiffusionPolicy, folder: Path, batch: int = 4, seed: int = 1) -> dict[str, float]:
    """Largest absolute difference between onnxruntime and torch for each exported graph on random inputs
    (`example_inputs`); a one-line `ToddlerbotError` above `TOLERANCE`."""
    inputs = example_inputs(policy, batch, seed)
    modules = {ENCODER_FILE: ObservationEncoder(policy), UNET_FILE: NoiseUnet(policy)}
    report = {}
    for name, module in modules.items():
        with torch.no_grad():
            expected = module(**inputs[name]).numpy()
        got = session(folder / name).run(None, {k: v.numpy() for k, v in inputs[name].items()})[0]
        if got.shape != expected.shape:
            raise ToddlerbotError(f"{folder / name}: output shape {got.shape}, torch gives {expected.shape}")
        report[name] = float(np.max(np.abs(got - expected)))
        report[f"{name} scale"] = float(np.max(np.abs(expected)))
    worst = max(report[name] for name in modules)
    if not worst <= TOLERANCE:
        raise ToddlerbotError(f"{folder}: ONNX outputs differ from torch by {worst:.3g} ("
                              + ", ".join(f"{n} {report[n]:.3g}" for n in modules) + f"); tolerance {TOLERANCE:g}")
    return report


def export_onnx(checkpoint: str | Path, folder: str | Path, binary_actions: tuple[str, ...] | None = None
                ) -> tuple[dict[str, Path], dict[str, float]]:
    """Write ``folder``/observation_encoder.onnx and ``folder``/noise_unet.onnx for a checkpoint's EMA network and
    check them against torch; returns the paths and the differences (`verify`). The graphs' metadata carries the
    config (``binary_actions`` replaced if given): a runtime snaps those actions after the last denoising step."""
    try:
        import onnx  # noqa: F401
        import onnxruntime  # noqa: F401
    except ImportError as exc:
        raise ToddlerbotError(f"dp export --format onnx needs the onnx package ([train] extra) and onnxruntime "
                              f"([onnx] extra): {exc}") from None
    from toddlerbot.dp.checkpoint import load_policy

    return export_policy_onnx(load_policy(checkpoint, binary_actions=binary_actions), folder, Path(checkpoint).name)


def export_policy_onnx(policy: DiffusionPolicy, folder: str | Path, source: str = "a DiffusionPolicy"
                       ) -> tuple[dict[str, Path], dict[str, float]]:
    """`export_onnx` of a network in memory (``source`` names it in the graphs' doc strings)."""
    policy = policy.cpu().eval()
    folder = Path(folder)
    inputs = example_inputs(policy)
    encoder_inputs = dict(inputs[ENCODER_FILE])
    paths = {ENCODER_FILE: folder / ENCODER_FILE, UNET_FILE: folder / UNET_FILE}
    _export(ObservationEncoder(policy), encoder_inputs, "cond", paths[ENCODER_FILE],
            _metadata(policy, "observation_encoder"), f"diffusion-policy observation encoder from {source}")
    _export(NoiseUnet(policy), inputs[UNET_FILE], "output", paths[UNET_FILE], _metadata(policy, "noise_unet"),
            f"diffusion-policy noise-prediction U-Net ({policy.config.prediction}) from {source}")
    try:
        report = verify(policy, folder)
    except ToddlerbotError:
        for path in paths.values():
            path.unlink(missing_ok=True)
        raise
    return paths, report
