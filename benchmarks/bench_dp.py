"""Diffusion-policy figures: training step time and inference time (3 DDPM steps, one observation) for the
small-CNN CPU configuration and the appendix-size ResNet-18 configuration.

    PYTHONPATH=src python benchmarks/bench_dp.py                  # one CPU thread, both configurations
    PYTHONPATH=src python benchmarks/bench_dp.py --device cuda    # on a GPU (threads setting ignored)
    PYTHONPATH=src python benchmarks/bench_dp.py --onnx           # networks per inference: torch vs onnxruntime

The appendix bounds inference at 0.1 s on a Jetson GPU; the issue's target for the shipped small configuration is
<= 50 ms on one CPU core. State and action are 16-d (two 7-joint arms and grippers), images 96x96.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
import torch

from toddlerbot.dp.config import PRESETS
from toddlerbot.dp.policy import DiffusionPolicy

DIM = 16


def batch(config, size: int, device: str) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(0)
    n, h = config.n_obs_steps, config.image_size
    return {
        "observation.state": torch.rand(size, n, DIM, generator=g).to(device),
        "observation.images.head": torch.randint(0, 256, (size, n, 3, h, h), generator=g, dtype=torch.uint8).to(device),
        "action": torch.rand(size, config.horizon, DIM, generator=g).to(device),
        "action_is_pad": torch.zeros(size, config.horizon, dtype=torch.bool).to(device),
    }


def timed(fn, repeats: int, device: str) -> tuple[np.ndarray, np.ndarray]:
    """Wall-clock and this thread's CPU seconds per call. On a shared machine the CPU time is the figure for
    "one core" (the wall time includes waiting for a core); with one torch thread all work runs on this thread."""
    wall, cpu = np.empty(repeats), np.empty(repeats)
    for i in range(repeats):
        if device == "cuda":
            torch.cuda.synchronize()
        start, start_cpu = time.perf_counter(), time.thread_time()
        fn()
        if device == "cuda":
            torch.cuda.synchronize()
        wall[i], cpu[i] = time.perf_counter() - start, time.thread_time() - start_cpu
    return wall, cpu


def bench(name: str, device: str, train_repeats: int, infer_repeats: int) -> None:
    config = PRESETS[name].with_dims(DIM, DIM)
    policy = DiffusionPolicy(config).to(device)
    params = sum(p.numel() for p in policy.parameters()) / 1e6
    optimizer = torch.optim.AdamW(policy.parameters(), lr=config.learning_rate)
    train_batch = batch(config, config.batch_size, device)

    def train_step() -> None:
        loss = policy.loss(train_batch)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()

    train_step()  # warm-up (allocations, kernels)
    train_wall, train_cpu = timed(train_step, train_repeats, device)
    policy.eval()
    one = {k: v[:1] for k, v in batch(config, 1, device).items() if k.startswith("observation")}
    with torch.inference_mode():
        policy.sample(one)
        infer_wall, infer_cpu = timed(lambda: policy.sample(one), infer_repeats, device)
    print(f"{name:8s} encoder {config.encoder:9s} U-Net {config.down_dims} {params:6.2f} M params\n"
          f"  train step (batch {config.batch_size}): median {np.median(train_wall):.3f} s wall, "
          f"{np.median(train_cpu):.3f} s CPU\n"
          f"  inference ({config.inference_steps} {config.sampler.upper()} steps, 1 observation): median "
          f"{np.median(infer_wall) * 1e3:.1f} ms wall (p90 {np.percentile(infer_wall, 90) * 1e3:.1f}), "
          f"{np.median(infer_cpu) * 1e3:.1f} ms CPU (p90 {np.percentile(infer_cpu, 90) * 1e3:.1f})")


def bench_onnx(name: str, repeats: int) -> None:
    """The networks of one inference (encoder once, U-Net per denoising step) in torch and in onnxruntime (the
    `dp export --format onnx` graphs), one thread each, timed alternately; the sampler's arithmetic is left out."""
    import tempfile

    from toddlerbot.dp.onnx_export import (
        ENCODER_FILE,
        UNET_FILE,
        example_inputs,
        export_policy_onnx,
        session,
    )

    config = PRESETS[name].with_dims(DIM, DIM)
    policy = DiffusionPolicy(config).eval()
    with tempfile.TemporaryDirectory() as tmp:
        paths, report = export_policy_onnx(policy, tmp)
        sessions = {k: session(p) for k, p in paths.items()}
    inputs = example_inputs(policy, batch=1)
    feeds = {k: {n: v.numpy() for n, v in inputs[k].items()} for k in inputs}
    steps = config.inference_steps

    def torch_networks() -> None:
        with torch.inference_mode():
            cond = policy.condition({"observation.state": inputs[ENCODER_FILE]["state"],
                                     **({"observation.images.head": inputs[ENCODER_FILE]["images"]}
                                        if "images" in inputs[ENCODER_FILE] else {})})
            for _ in range(steps):
                policy.unet(inputs[UNET_FILE]["sample"], inputs[UNET_FILE]["timestep"], cond)

    def onnx_networks() -> None:
        cond = sessions[ENCODER_FILE].run(None, feeds[ENCODER_FILE])[0]
        for _ in range(steps):
            sessions[UNET_FILE].run(None, {**feeds[UNET_FILE], "cond": cond})

    torch_networks(), onnx_networks()  # warm-up
    times = {"torch": [], "onnxruntime": []}
    for _ in range(repeats):
        for label, fn in (("torch", torch_networks), ("onnxruntime", onnx_networks)):
            times[label].append(timed(fn, 1, "cpu"))
    print(f"{name:8s} networks of one inference (encoder + {steps} U-Net steps), one thread; ONNX vs torch max abs "
          f"difference: encoder {report[ENCODER_FILE]:.1g}, U-Net {report[UNET_FILE]:.1g}")
    for label, rows in times.items():
        wall = np.concatenate([w for w, _ in rows])
        cpu = np.concatenate([c for _, c in rows])
        print(f"  {label:12s} median {np.median(wall) * 1e3:.1f} ms wall (p90 {np.percentile(wall, 90) * 1e3:.1f}), "
              f"{np.median(cpu) * 1e3:.1f} ms CPU (p90 {np.percentile(cpu, 90) * 1e3:.1f})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--configs", nargs="+", default=["small", "appendix"], choices=sorted(PRESETS))
    parser.add_argument("--train-repeats", type=int, default=5)
    parser.add_argument("--infer-repeats", type=int, default=30)
    parser.add_argument("--onnx", action="store_true", help="only: the networks of one inference in torch and in "
                                                              "onnxruntime (dp export --format onnx), one thread")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    where = torch.cuda.get_device_name() if args.device == "cuda" else f"{platform.processor() or 'cpu'}, " \
        f"{args.threads} thread(s)"
    print(f"torch {torch.__version__} on {args.device} ({where}); load average {os.getloadavg()[0]:.1f} on "
          f"{os.cpu_count()} cores")
    for name in args.configs:
        if args.onnx:
            bench_onnx(name, args.infer_repeats)
        else:
            bench(name, args.device, args.train_repeats, args.infer_repeats)


if __name__ == "__main__":
    main()
