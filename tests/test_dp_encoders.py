"""Image encoders: shapes, GroupNorm everywhere, and ImageNet weights from a local torchvision-style file."""

import pytest

torch = pytest.importorskip("torch")

from toddlerbot.dp.encoders import ResNet18Encoder, SmallCNNEncoder  # noqa: E402
from toddlerbot.dp.imagenet import (  # noqa: E402
    PretrainedWeightsError,
    load_imagenet_weights,
    torchvision_key,
)

torch.set_num_threads(1)


def torchvision_style_state_dict(seed: int) -> dict:
    """What torchvision's resnet18().state_dict() holds (names and shapes), with BatchNorm statistics and fc."""
    generator = torch.Generator().manual_seed(seed)
    state = {}
    for name, tensor in ResNet18Encoder().state_dict().items():
        if name.startswith("project."):
            continue
        key = torchvision_key(name)
        state[key] = torch.randn(tensor.shape, generator=generator)
        if ".bn" in f".{key}" or key.endswith("downsample.1.weight"):
            stem = key.rsplit(".", 1)[0]
            state[f"{stem}.running_mean"] = torch.zeros(tensor.shape)
            state[f"{stem}.running_var"] = torch.ones(tensor.shape)
            state[f"{stem}.num_batches_tracked"] = torch.tensor(100)
    state["fc.weight"], state["fc.bias"] = torch.randn(1000, 512, generator=generator), torch.zeros(1000)
    return state


def test_encoders_give_one_feature_vector_per_image_and_use_no_batchnorm():
    images = torch.rand(3, 3, 96, 96)
    for encoder, dim in ((ResNet18Encoder(32), 32), (SmallCNNEncoder((8, 16), 12), 12)):
        assert encoder(images).shape == (3, dim)
        assert not any(isinstance(m, torch.nn.modules.batchnorm._BatchNorm) for m in encoder.modules())
    # per-sample normalisation: an image's features do not depend on the rest of the batch
    encoder = ResNet18Encoder(8).eval()
    assert torch.allclose(encoder(images)[:1], encoder(images[:1]), atol=1e-5)


def test_imagenet_state_dict_from_a_local_file_fills_convolutions_and_groupnorm_affines(tmp_path):
    path = tmp_path / "resnet18_imagenet.pt"
    source = torchvision_style_state_dict(seed=1)
    torch.save(source, path)
    encoder = ResNet18Encoder(16)
    report = load_imagenet_weights(encoder, path)
    assert torch.equal(encoder.conv1.weight, source["conv1.weight"])
    assert torch.equal(encoder.layer3[0].norm2.weight, source["layer3.0.bn2.weight"])  # BN affine -> GN affine
    assert torch.equal(encoder.layer2[0].downsample[1].bias, source["layer2.0.downsample.1.bias"])
    assert len(report["loaded"]) == 60  # 20 convolutions + 20 norms x (weight, bias)
    assert "fc.weight" in report["dropped"] and "bn1.running_var" in report["dropped"]
    assert all(k.startswith("fc.") or k.endswith(("running_mean", "running_var", "num_batches_tracked"))
               for k in report["dropped"])


def test_wrong_or_missing_weight_files_are_refused_in_one_line(tmp_path):
    state = torchvision_style_state_dict(seed=2)
    state["layer1.0.conv1.weight"] = torch.zeros(64, 64, 1, 1)
    wrong = tmp_path / "wrong.pt"
    torch.save(state, wrong)
    with pytest.raises(PretrainedWeightsError, match=r"wrong\.pt: layer1\.0\.conv1\.weight has shape"):
        load_imagenet_weights(ResNet18Encoder(), wrong)
    with pytest.raises(PretrainedWeightsError, match="no such file"):
        load_imagenet_weights(ResNet18Encoder(), tmp_path / "absent.pt")
