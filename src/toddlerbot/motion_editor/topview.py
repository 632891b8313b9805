"""A top view of the balance for the side panel: the soles, the support polygon and the CoM's ground projection.

In 3D the polygon and the CoM marker sit under and inside the robot; this small picture is never hidden. Drawn with
Pillow (already needed by imageio): a few polygons, well under a millisecond.
"""

from __future__ import annotations

import numpy as np
from PIL import Image, ImageDraw

from toddlerbot.motion_editor.balance import Balance

SIZE_PX = 220
HALF_SPAN_M = 0.11
"""Half the width of the area shown, m, centred between the soles."""
SOLE, GRID = (180, 180, 185), (235, 235, 235)
GREEN, RED = (40, 170, 70), (220, 50, 40)


def top_view(balance: Balance, soles: list[np.ndarray]) -> np.ndarray:
    """(SIZE_PX, SIZE_PX, 3) uint8 picture, x (forward) up, y (left) to the left; a 1 cm grid."""
    image = Image.new("RGB", (SIZE_PX, SIZE_PX), "white")
    draw = ImageDraw.Draw(image)
    centre = np.mean(np.concatenate(soles), axis=0) if soles else balance.com[:2]
    scale = SIZE_PX / (2 * HALF_SPAN_M)

    def px(points: np.ndarray) -> list[tuple[float, float]]:
        rel = (np.asarray(points).reshape(-1, 2) - centre) * scale
        return [(SIZE_PX / 2 - y, SIZE_PX / 2 - x) for x, y in rel]

    for k in range(-11, 12):
        at = SIZE_PX / 2 + k * 0.01 * scale
        draw.line([(at, 0), (at, SIZE_PX)], fill=GRID)
        draw.line([(0, at), (SIZE_PX, at)], fill=GRID)
    for sole in soles:
        draw.polygon(px(sole), fill=SOLE)
    color = GREEN if balance.supported else RED
    if len(balance.polygon) >= 2:
        ring = px(balance.polygon)
        draw.line([*ring, ring[0]], fill=color, width=2)
    (cx, cy), r = px(balance.com[:2])[0], 5
    draw.ellipse([cx - r, cy - r, cx + r, cy + r], fill=color)
    draw.line([(8, SIZE_PX - 10), (8 + 0.05 * scale, SIZE_PX - 10)], fill=(60, 60, 60), width=2)
    draw.text((10, SIZE_PX - 24), "5 cm", fill=(60, 60, 60))
    draw.text((SIZE_PX / 2 - 18, 4), "front", fill=(60, 60, 60))
    return np.asarray(image)
