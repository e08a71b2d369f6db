"""Sampling images at surface positions (shared by the stages)."""

from __future__ import annotations

import numpy as np

__all__ = ["_bilinear"]


def _bilinear(img: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Sample img (..., H, W) at float pixel positions xy (N, 2) -> (..., N)."""
    h, w = img.shape[-2:]
    x = np.clip(xy[:, 0], 0, w - 1)
    y = np.clip(xy[:, 1], 0, h - 1)
    x0 = np.minimum(np.floor(x).astype(int), w - 2) if w > 1 else np.zeros(len(x), int)
    y0 = np.minimum(np.floor(y).astype(int), h - 2) if h > 1 else np.zeros(len(y), int)
    fx, fy = x - x0, y - y0
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    return (
        img[..., y0, x0] * (1 - fx) * (1 - fy)
        + img[..., y0, x1] * fx * (1 - fy)
        + img[..., y1, x0] * (1 - fx) * fy
        + img[..., y1, x1] * fx * fy
    )
