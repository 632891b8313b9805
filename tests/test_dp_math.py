"""Diffusion policy pieces with closed forms: normalisation, image scaling, the noise schedule and its samplers."""

import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from toddlerbot.dp.normalize import (  # noqa: E402
    ImageFormatError,
    MinMaxNormalizer,
    crop_images,
    images_to_unit,
)
from toddlerbot.dp.scheduler import NoiseSchedule  # noqa: E402

torch.set_num_threads(1)


def test_min_max_normalisation_maps_range_to_unit_interval_and_round_trips():
    rng = np.random.default_rng(0)
    data = rng.uniform([-2.0, 0.5, 3.0], [1.0, 0.7, 3.0], (200, 3)).astype(np.float32)  # last dim constant
    norm = MinMaxNormalizer(3).fit(data.min(0), data.max(0))
    x = torch.as_tensor(data)
    y = norm.normalize(x)
    assert torch.allclose(y[:, :2].min(0).values, torch.tensor([-1.0, -1.0]), atol=1e-6)
    assert torch.allclose(y[:, :2].max(0).values, torch.tensor([1.0, 1.0]), atol=1e-6)
    assert torch.all(y[:, 2] == 0.0)  # a constant dimension is centred, not blown up
    assert torch.allclose(norm.unnormalize(y), x, atol=1e-6)
    midpoint = torch.as_tensor((data.min(0) + data.max(0)) / 2)[None]
    assert torch.allclose(norm.normalize(midpoint), torch.zeros(1, 3), atol=1e-6)


def test_normaliser_ranges_survive_a_state_dict_round_trip():
    a = MinMaxNormalizer(2).fit(np.array([0.0, -1.0]), np.array([2.0, 3.0]))
    b = MinMaxNormalizer(2)
    b.load_state_dict(a.state_dict())
    assert torch.equal(b.centre, torch.tensor([1.0, 1.0])) and torch.equal(b.half_range, torch.tensor([1.0, 2.0]))


def test_images_are_scaled_once_from_uint8_and_floats_are_refused():
    images = torch.tensor([0, 51, 255], dtype=torch.uint8).view(1, 3, 1, 1).expand(1, 3, 2, 2)
    unit = images_to_unit(images)
    assert unit.dtype == torch.float32
    assert unit[0, :, 0, 0].tolist() == pytest.approx([0.0, 0.2, 1.0])
    with pytest.raises(ImageFormatError, match="uint8"):
        images_to_unit(unit)  # an already-scaled image cannot be scaled again
    with pytest.raises(ImageFormatError, match="3, H, W"):
        images_to_unit(torch.zeros(1, 4, 2, 2, dtype=torch.uint8))


def test_training_crops_are_random_windows_and_inference_takes_the_centre():
    rows = torch.arange(10.0).view(1, 1, 10, 1).expand(64, 3, 10, 10)  # pixel value = its row
    centre = crop_images(rows, 6, random=False)
    assert centre.shape == (64, 3, 6, 6) and centre[0, 0, :, 0].tolist() == [2.0, 3.0, 4.0, 5.0, 6.0, 7.0]
    torch.manual_seed(0)
    tops = crop_images(rows, 6, random=True)[:, 0, 0, 0]
    assert set(tops.tolist()) == {0.0, 1.0, 2.0, 3.0, 4.0}  # every offset 0..H-size occurs in 64 draws
    assert crop_images(rows, 0, random=True) is rows


def cosine_alpha_bar(t: int, n: int = 100) -> float:
    f = lambda u: math.cos((u + 0.008) / 1.008 * math.pi / 2) ** 2  # noqa: E731
    return f((t + 1) / n) / f(0)


def test_cosine_schedule_matches_its_closed_form_and_three_steps_visit_66_33_0():
    schedule = NoiseSchedule(100)
    for t in (0, 10, 50, 90):
        assert float(schedule.alpha_bar[t]) == pytest.approx(cosine_alpha_bar(t), rel=1e-9)
    assert schedule.inference_timesteps(3) == [66, 33, 0]
    assert schedule.inference_timesteps(100)[:2] == [99, 98]


def test_forward_process_is_sqrt_alpha_bar_mix_of_sample_and_noise():
    schedule = NoiseSchedule(100)
    x0, eps = torch.randn(4, 16, 2), torch.randn(4, 16, 2)
    t = torch.tensor([0, 33, 66, 99])
    xt = schedule.add_noise(x0, eps, t)
    for i, step in enumerate(t.tolist()):
        ab = cosine_alpha_bar(step) if step < 99 else float(schedule.alpha_bar[99])
        expected = math.sqrt(ab) * x0[i] + math.sqrt(1 - ab) * eps[i]
        assert torch.allclose(xt[i], expected, atol=1e-5)


def test_ddpm_and_ddim_steps_with_the_true_noise_follow_the_posterior_formulas():
    schedule = NoiseSchedule(100, clip_sample=0.0)
    x0 = torch.rand(2, 16, 3) - 0.5
    eps, z = torch.randn(2, 16, 3), torch.randn(2, 16, 3)
    t, s = 66, 33
    xt = schedule.add_noise(x0, eps, torch.tensor([t, t]))
    ab_t, ab_s = cosine_alpha_bar(t), cosine_alpha_bar(s)
    beta = 1 - ab_t / ab_s
    mean = math.sqrt(ab_s) * beta / (1 - ab_t) * x0 + math.sqrt(ab_t / ab_s) * (1 - ab_s) / (1 - ab_t) * xt
    std = math.sqrt((1 - ab_s) / (1 - ab_t) * beta)
    assert torch.allclose(schedule.ddpm_step(xt, eps, t, s, z), mean + std * z, atol=1e-5)
    assert torch.allclose(schedule.ddpm_step(xt, eps, t, -1, z), x0, atol=1e-5)  # last step: the clean sample
    ddim = schedule.ddim_step(xt, eps, t, s)
    assert torch.allclose(ddim, math.sqrt(ab_s) * x0 + math.sqrt(1 - ab_s) * eps, atol=1e-5)


def test_predicted_clean_sample_is_clipped_to_the_normalised_range():
    schedule = NoiseSchedule(100, clip_sample=1.0)
    x0 = torch.full((1, 16, 1), 3.0)
    eps = torch.zeros_like(x0)
    xt = schedule.add_noise(x0, eps, torch.tensor([50]))
    assert torch.allclose(schedule.predict_x0(xt, eps, 50), torch.ones_like(x0))
