"""Comparing two rendered images (for image tests)."""
from __future__ import annotations

import numpy as np


def image_difference(a, b, threshold: int = 24) -> float:
    """Fraction (0..1) of pixels whose colour differs visibly between PNGs ``a`` and ``b``.

    A pixel differs when any of its R, G, B values (0..255) differs by more than ``threshold``.
    Images of different sizes differ everywhere (1.0). A fraction, not a mean colour error, so that a
    change confined to part of the map is not averaged away by the white background.
    """
    from PIL import Image
    ia = np.asarray(Image.open(a).convert("RGB"), dtype=np.int16)
    ib = np.asarray(Image.open(b).convert("RGB"), dtype=np.int16)
    if ia.shape != ib.shape:
        return 1.0
    return float(np.mean(np.max(np.abs(ia - ib), axis=2) > threshold))
