"""Diffusion-policy training: the loss falls, the split is by episode, checkpoints rebuild and resume exactly."""

import dataclasses
import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from dp_support import SyntheticWindows  # noqa: E402
from toddlerbot.dp.checkpoint import (  # noqa: E402
    CheckpointError,
    export_policy,
    load_policy,
    load_training_state,
)
from toddlerbot.dp.config import TINY, DPConfig, DPConfigError  # noqa: E402
from toddlerbot.dp.data import DatasetError, split_by_episode, value_ranges  # noqa: E402
from toddlerbot.dp.inference import PolicyInference  # noqa: E402
from toddlerbot.dp.policy import DiffusionPolicy  # noqa: E402
from toddlerbot.dp.train import TrainSchedule, train  # noqa: E402

torch.set_num_threads(1)


def test_tiny_configuration_trains_and_loss_falls_by_3x(tmp_path):
    data = SyntheticWindows()
    result = train(data, TINY, tmp_path, schedule=TrainSchedule(max_steps=60, log_every=20, val_batches=2),
                   show_progress=False)
    first, last = result.history[0], result.history[-1]
    assert [h["step"] for h in result.history] == [20, 40, 60]
    assert last["train_loss"] <= first["train_loss"] / 3
    assert last["val_loss"] <= first["val_loss"] / 2
    assert (tmp_path / "loss_curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads((tmp_path / "metrics.json").read_text())[-1]["step"] == 60
    # the ranges fitted on the training episodes travel inside the checkpoint
    policy = load_policy(result.checkpoint)
    train_set, _, _ = split_by_episode(data, TINY.val_fraction, TINY.seed)
    lo, hi = value_ranges(train_set)["action"]
    assert torch.allclose(policy.action_norm.normalize(torch.as_tensor(np.stack([lo, hi]))),
                          torch.tensor([[-1.0, -1.0], [1.0, 1.0]]), atol=1e-5)


def test_split_keeps_every_window_of_an_episode_on_one_side():
    data = SyntheticWindows(episodes=10, frames=7)
    train_set, val_set, info = split_by_episode(data, 0.2, seed=3)
    train_eps = {int(data.episodes[i]) for i in train_set.indices}
    val_eps = {int(data.episodes[i]) for i in val_set.indices}
    assert train_eps.isdisjoint(val_eps) and len(val_eps) == 2
    assert sorted(train_eps | val_eps) == list(range(10))
    assert len(train_set) + len(val_set) == len(data) and len(val_set) == 14
    assert info == {"train_episodes": sorted(train_eps), "val_episodes": sorted(val_eps)}
    # reading episode_index from the samples gives the same split as the window_episodes attribute
    _, val_again, _ = split_by_episode(SyntheticWindows(episodes=10, frames=7, with_episode_attribute=False), 0.2, 3)
    assert val_again.indices == val_set.indices
    with pytest.raises(DatasetError, match="1 episode"):
        split_by_episode(SyntheticWindows(episodes=1), 0.1, 0)


def test_three_ddpm_steps_recover_a_fixed_action_chunk():
    config = dataclasses.replace(TINY, encoder="none", state_dim=1, action_dim=1, learning_rate=3e-3)
    torch.manual_seed(0)
    policy = DiffusionPolicy(config)
    policy.action_norm.fit([-1.5], [1.5])
    target = (0.8 * torch.sin(torch.linspace(0, 3, 16))).view(1, 16, 1)
    batch = {"observation.state": torch.zeros(32, 2, 1), "action": target.expand(32, 16, 1),
             "action_is_pad": torch.zeros(32, 16, dtype=torch.bool)}
    optimizer = torch.optim.AdamW(policy.parameters(), lr=config.learning_rate)
    for _ in range(60):
        loss = policy.loss(batch)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    policy.eval()
    chunk = policy.sample({"observation.state": torch.zeros(8, 2, 1)}, torch.Generator().manual_seed(1))
    assert config.inference_steps == 3 and config.sampler == "ddpm"
    assert float((chunk - target).abs().max()) < 0.05  # of a 3.0-wide action range


def test_resumed_training_matches_an_uninterrupted_run_exactly(tmp_path):
    data = SyntheticWindows(episodes=4, frames=8)
    schedule = TrainSchedule(log_every=4, val_batches=1)
    whole = train(data, TINY, tmp_path / "whole", schedule=dataclasses.replace(schedule, max_steps=8),
                  show_progress=False)
    train(data, TINY, tmp_path / "split", schedule=dataclasses.replace(schedule, max_steps=4), show_progress=False)
    resumed = train(data, TINY, tmp_path / "split", resume=True,
                    schedule=dataclasses.replace(schedule, max_steps=8), show_progress=False)
    assert resumed.step == whole.step == 8
    a, b = load_training_state(whole.checkpoint), load_training_state(resumed.checkpoint)
    for name, tensor in a.policy.state_dict().items():
        assert torch.equal(tensor, b.policy.state_dict()[name]), name
    for name, tensor in a.ema.model.state_dict().items():
        assert torch.equal(tensor, b.ema.model.state_dict()[name]), name
    assert a.ema.updates == b.ema.updates == 8
    sample = {k: np.asarray(v) for k, v in data[0].items() if k.startswith("observation")}
    chunk_a = PolicyInference.from_checkpoint(whole.checkpoint, seed=5)(sample)
    chunk_b = PolicyInference.from_checkpoint(resumed.checkpoint, seed=5)(sample)
    assert chunk_a.shape == (16, 2) and np.array_equal(chunk_a, chunk_b)


def test_checkpoint_rebuilds_its_network_and_inference_matches_the_training_pipeline(tmp_path):
    data = SyntheticWindows(episodes=3, frames=6)
    result = train(data, TINY, tmp_path, schedule=TrainSchedule(max_steps=2, log_every=1, val_batches=1),
                   show_progress=False)
    policy = load_policy(result.checkpoint)  # nothing but the file
    assert policy.config.state_dim == 3 and policy.config.action_dim == 2 and not policy.training
    assert policy.config.state_names == ("joint_0", "joint_1", "joint_2")  # the dataset's names travel along
    assert policy.config.action_names == ("target_0", "target_1")
    sample = data[1]
    batch = {"observation.state": torch.as_tensor(sample["observation.state"])[None],
             "observation.images.head": torch.as_tensor(sample["observation.images.head"])[None]}
    direct = policy.sample(batch, torch.Generator().manual_seed(9))[0].numpy()
    via_runner_callable = PolicyInference(policy, seed=9)(
        {k: sample[k] for k in ("observation.state", "observation.images.head")})
    assert np.array_equal(direct, via_runner_callable)


def test_broken_checkpoints_and_configs_are_refused_in_one_line(tmp_path):
    truncated = tmp_path / "truncated.pt"
    truncated.write_bytes(b"PK\x03\x04 not really a checkpoint")
    with pytest.raises(CheckpointError, match=r"truncated\.pt: not a weights-only torch checkpoint"):
        load_policy(truncated)
    pickled = tmp_path / "pickled.pt"
    torch.save({"format": "toddlerbot-dp/1", "config": tmp_path}, pickled)  # a Path object needs unpickling
    with pytest.raises(CheckpointError, match=r"pickled\.pt"):
        load_policy(pickled)
    with pytest.raises(CheckpointError, match="no such checkpoint"):
        load_policy(tmp_path / "missing.pt")
    with pytest.raises(DPConfigError, match="unknown config field"):
        DPConfig.from_json('{"horizon": 16, "hoirzon": 8}', source="run/config.json")
    with pytest.raises(DPConfigError, match="latency_drop \\+ n_action_steps = 18 > horizon 16"):
        DPConfig(latency_drop=3, n_action_steps=15)
    assert DPConfig.from_json(TINY.to_json()) == TINY


def test_the_image_path_conditions_the_chunk():
    """The action is the image's brightness (the state is constant): the policy must read it from the camera."""
    torch.set_num_threads(1)  # the measured figures are for one thread (float sums differ with more)
    torch.manual_seed(0)
    config = dataclasses.replace(TINY, learning_rate=3e-3).with_dims(1, 1)
    policy = DiffusionPolicy(config)
    policy.action_norm.fit([-1.0], [1.0])

    def windows(n, generator):
        level = torch.rand(n, generator=generator)
        images = (level * 255).round().to(torch.uint8).view(n, 1, 1, 1, 1).expand(n, 2, 3, 16, 16).contiguous()
        return {"observation.state": torch.zeros(n, 2, 1), "observation.images.head": images,
                "action": (level * 1.6 - 0.8).view(n, 1, 1).expand(n, 16, 1).contiguous(),
                "action_is_pad": torch.zeros(n, 16, dtype=torch.bool)}

    generator = torch.Generator().manual_seed(0)
    optimizer = torch.optim.AdamW(policy.parameters(), lr=config.learning_rate)
    for _ in range(200):
        loss = policy.loss(windows(32, generator))
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    policy.eval()
    test = windows(16, torch.Generator().manual_seed(99))
    error = float((policy.sample(test, torch.Generator().manual_seed(1)) - test["action"]).abs().mean())
    blind = float((test["action"] - test["action"].mean()).abs().mean())  # best guess without the image
    assert error < 0.5 * blind  # measured: 0.09 against 0.50


def test_binary_actions_snap_to_the_demonstrated_open_or_closed_end(tmp_path):
    """A gripper demonstrated closing to 0.78 of its range: the sampled command lands on 0.78 or on open, never
    just short of the closed value (where the chain's "commanded closed" check fails)."""
    data = SyntheticWindows(episodes=3, frames=6)
    result = train(data, dataclasses.replace(TINY, binary_actions=("target_1",)), tmp_path / "run",
                   schedule=TrainSchedule(max_steps=2, log_every=1, val_batches=1), show_progress=False)
    policy = load_policy(result.checkpoint)
    assert policy.config.binary_actions == ("target_1",)
    lo, hi = (float(policy.action_norm.unnormalize(torch.full((1, 2), v))[0, 1]) for v in (-1.0, 1.0))
    sample = data[1]
    batch = {k: torch.as_tensor(sample[k])[None].expand(64, *np.shape(sample[k]))
             for k in ("observation.state", "observation.images.head")}
    chunk = policy.sample(batch, torch.Generator().manual_seed(3))
    gripper = chunk[..., 1].flatten()
    assert torch.all((gripper == lo) | (gripper == hi)) and lo < hi
    plain = load_policy(result.checkpoint, binary_actions=())
    free = plain.sample(batch, torch.Generator().manual_seed(3))
    assert torch.equal(free[..., 0], chunk[..., 0])  # the other action is untouched
    inside = (free[..., 1] > lo + 1e-3) & (free[..., 1] < hi - 1e-3)
    assert float(inside.float().mean()) > 0.5  # unsnapped, an untrained network's samples lie between the ends
    expected = torch.where(free[..., 1] > (lo + hi) / 2, hi, lo)
    assert torch.allclose(chunk[..., 1], expected)
    # set on export, replacing the checkpoint's; an unknown name is refused in one line, nothing written
    exported = export_policy(result.checkpoint, tmp_path / "plain.pt", binary_actions=())
    assert load_policy(exported).config.binary_actions == ()
    with pytest.raises(DPConfigError, match=r"binary_actions \['gripper'\] \(expected distinct action names, of "
                                            r"target_0, target_1\)"):
        export_policy(result.checkpoint, tmp_path / "bad.pt", binary_actions=("gripper",))
    assert not (tmp_path / "bad.pt").exists()
    with pytest.raises(DPConfigError, match="binary_actions"):
        dataclasses.replace(TINY, binary_actions=("a", "a"))
