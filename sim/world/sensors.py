"""Sensor transfer functions: what a device outputs for what it senses, in its own units.

Geometry (ray casts, floor sampling) lives in `sim.world`; here are the curves: IR distance ->
raw value (c't-Sim's measured characteristic tables, `bots.ir_curve`), the firmware's way back,
floor colour -> CNY70 value, light distance -> LDR darkness (ctsim-reference.md §2).
"""

from __future__ import annotations

import numpy as np

CNY70_MAX = 1023
LDR_MAX = 1023


def absorption(colour: np.ndarray) -> np.ndarray:
    """The share of a CNY70's light a floor colour (..., 3) in 0..1 swallows, 1 - mean(RGB), in
    c't-Sim's float32 arithmetic (`World.sensGroundReflectionLine`); a hole swallows 1."""
    rgb = np.asarray(colour, dtype=np.float32)
    return np.float32(1.0) - (rgb[..., 0] + rgb[..., 1] + rgb[..., 2]) / np.float32(3.0)


def cny70_value(colour: np.ndarray) -> np.ndarray:
    """CNY70 reflex sensor value of a uniform floor colour (..., 3): its absorption scaled to
    0 (white) .. 1023 (black) and truncated, as c't-Sim (normal floor #606060 -> 637, goal
    #66FF00 -> 545). Sensors average a cross of rays: `kernels.sensing.sample_floor`."""
    return np.floor(absorption(colour) * np.float32(CNY70_MAX)).astype(np.int64)


def ldr_value(distance: np.ndarray, reach: float = 1.0) -> np.ndarray:
    """LDR darkness for the distance (m) to the nearest visible lamp surface: linear, truncated,
    1023 at `reach` or with no light (inf), as c't-Sim's `World.sensLight`."""
    d = np.asarray(distance, dtype=np.float64)
    return np.floor(np.minimum(d / reach, 1.0) * LDR_MAX).astype(np.int64)
