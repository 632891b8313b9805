"""Data-parallel training over processes with torch.distributed, as launched by ``torchrun``.

``torchrun --nproc-per-node N`` (or one ``torchrun`` per machine with ``--nnodes``/``--rdzv-endpoint``) starts N
copies of ``toddlerbot dp train`` with ``RANK``, ``WORLD_SIZE``, ``LOCAL_RANK``, ``MASTER_ADDR`` and
``MASTER_PORT`` set; `join` reads them through torch.distributed's ``env://`` initialisation. On the CPU the
processes talk through gloo; on GPUs through NCCL, one GPU per local rank. Without ``WORLD_SIZE`` (or with 1) a run
is a single process and nothing here is used.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import torch
import torch.distributed as dist
from torch import nn

from toddlerbot.dp.config import DPConfigError


@dataclass(frozen=True)
class DataParallel:
    """This process's place in a data-parallel run."""

    rank: int
    world_size: int
    device: torch.device
    owns_group: bool
    """Whether `join` started the process group (and `leave` ends it)."""

    @property
    def main(self) -> bool:
        """Rank 0: the one process that writes the checkpoint, records and plots."""
        return self.rank == 0

    def rows(self, global_batch: int) -> slice:
        """This rank's rows of a global batch: each rank takes ``global_batch / world_size`` consecutive rows."""
        return batch_rows(global_batch, self.world_size, self.rank)

    def wrap(self, module: nn.Module) -> nn.Module:
        """``module`` under DistributedDataParallel (its weights and buffers broadcast from rank 0); gradients are
        averaged over the ranks in the backward pass."""
        ids = [self.device.index] if self.device.type == "cuda" else None
        # the buffers (normaliser ranges) never change in training: synced at init, not before every forward
        return nn.parallel.DistributedDataParallel(module, device_ids=ids, forward_sync_buffers=False)

    def broadcast(self, module: nn.Module) -> None:
        """Copy rank 0's weights and buffers of ``module`` into every rank's."""
        with torch.no_grad():
            for tensor in [*module.parameters(), *module.buffers()]:
                dist.broadcast(tensor.data, src=0)

    def sum(self, tensor: torch.Tensor) -> torch.Tensor:
        """The sum of ``tensor`` over the ranks (a new tensor; no gradient)."""
        total = tensor.detach().clone()
        dist.all_reduce(total)
        return total

    def decide(self, flag: bool) -> bool:
        """Rank 0's ``flag`` on every rank (a wall-time stop must stop all ranks at the same step)."""
        value = torch.tensor([int(flag)], device=self.device)
        dist.broadcast(value, src=0)
        return bool(value.item())

    def agree(self, what: str, value: object) -> None:
        """Refuse in one line when a rank's ``value`` differs from rank 0's (e.g. another copy of the dataset)."""
        values: list[object] = [None] * self.world_size
        dist.all_gather_object(values, value)
        for rank, other in enumerate(values):
            if other != values[0]:
                raise DPConfigError(f"rank {rank} has {what} {other}, rank 0 has {values[0]}: every process must "
                                    "train on the same dataset and run directory")

    def leave(self) -> None:
        if self.owns_group and dist.is_initialized():
            dist.destroy_process_group()


def launched_rank() -> int:
    """The ``RANK`` a launcher gave this process (0 when launched alone), known before `join`."""
    return int(os.environ.get("RANK", "0"))


def batch_rows(global_batch: int, world_size: int, rank: int) -> slice:
    """Rows ``rank`` takes of a ``global_batch`` split over ``world_size`` processes; one line when it does not split
    evenly (the global batch is the configured one, whatever the number of processes)."""
    if global_batch % world_size:
        raise DPConfigError(f"batch size {global_batch} does not split evenly over {world_size} processes "
                            f"(WORLD_SIZE); give a --batch-size divisible by {world_size}")
    part = global_batch // world_size
    return slice(rank * part, (rank + 1) * part)


def join(device: torch.device) -> DataParallel | None:
    """This process's `DataParallel` when a launcher started several (``WORLD_SIZE`` > 1), else None. Starts the
    process group through ``env://`` (unless the caller did): gloo on the CPU, NCCL on CUDA, where ``device`` (a
    plain ``cuda``) becomes the GPU of this process's ``LOCAL_RANK``."""
    world_size = int(os.environ.get("WORLD_SIZE", "1"))
    if world_size <= 1:
        return None
    if device.type == "cuda":
        local_rank = int(os.environ.get("LOCAL_RANK", "0"))
        if device.index is not None:
            raise DPConfigError(f"device {device} with {world_size} processes: each process takes the GPU of its "
                                "LOCAL_RANK; give --device cuda (choose GPUs with CUDA_VISIBLE_DEVICES)")
        if local_rank >= torch.cuda.device_count():
            raise DPConfigError(f"LOCAL_RANK {local_rank}: this machine has {torch.cuda.device_count()} GPU(s); "
                                "start at most that many processes per machine (--nproc-per-node)")
        device = torch.device("cuda", local_rank)
        torch.cuda.set_device(device)
    elif device.type != "cpu":
        raise DPConfigError(f"device {device}: data-parallel training runs on cpu (gloo) or cuda (NCCL)")
    owns_group = not dist.is_initialized()
    if owns_group:
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo", init_method="env://",
                                device_id=device if device.type == "cuda" else None)
    if dist.get_world_size() != world_size:
        raise DPConfigError(f"WORLD_SIZE {world_size}, but the process group has {dist.get_world_size()} processes")
    return DataParallel(dist.get_rank(), world_size, device, owns_group)
