"""A synthetic window dataset for the diffusion-policy tests (made in memory, nothing downloaded)."""

from __future__ import annotations

import numpy as np


class SyntheticWindows:
    """``episodes`` episodes of ``frames`` windows; the action chunk is a smooth function of the state, and the
    image's brightness encodes the state's first dimension (so an image encoder has something to see).

    ``with_episode_attribute=False`` hides ``window_episodes`` so the split reads ``episode_index`` per sample.
    """

    def __init__(self, episodes: int = 6, frames: int = 12, state_dim: int = 3, action_dim: int = 2,
                 n_obs: int = 2, horizon: int = 16, image_size: int = 24, with_episode_attribute: bool = True,
                 seed: int = 0) -> None:
        rng = np.random.default_rng(seed)
        self.n_obs, self.horizon, self.image_size = n_obs, horizon, image_size
        self.episodes = np.repeat(np.arange(episodes), frames)
        self.state = rng.uniform(-0.5, 0.5, (episodes * frames, state_dim)).astype(np.float32)
        self.action_dim = action_dim
        self.pad_from = rng.integers(horizon // 2, horizon + 1, episodes * frames)
        self.state_names = tuple(f"joint_{i}" for i in range(state_dim))
        self.action_names = tuple(f"target_{i}" for i in range(action_dim))
        if with_episode_attribute:
            self.window_episodes = self.episodes

    def __len__(self) -> int:
        return len(self.episodes)

    def __getitem__(self, i: int) -> dict:
        s = self.state[i]
        state = np.stack([s - 0.01 * (self.n_obs - 1 - k) for k in range(self.n_obs)]).astype(np.float32)
        ramp = np.linspace(0.0, 1.0, self.horizon, dtype=np.float32)[:, None]
        action = (s[: self.action_dim][None] + 0.3 * ramp * np.arange(1, self.action_dim + 1)).astype(np.float32)
        is_pad = np.arange(self.horizon) >= self.pad_from[i]
        action[is_pad] = action[~is_pad][-1]
        level = np.uint8(round(255 * (s[0] + 0.5)))
        images = np.full((self.n_obs, 3, self.image_size, self.image_size), level, dtype=np.uint8)
        return {"observation.state": state, "observation.images.head": images, "action": action,
                "action_is_pad": is_pad, "episode_index": int(self.episodes[i])}
