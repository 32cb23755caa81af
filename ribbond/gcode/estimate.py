"""Print-time estimate of a move list, with accelerations and Marlin's junction deviation.

Each move accelerates from its entry speed to its feed rate and decelerates to its exit speed
(trapezoid; a short move peaks lower). The speed through a corner between two moves is limited by
Marlin's junction-deviation rule, v = sqrt(a δ sin(θ/2) / (1 − sin(θ/2))) with θ the angle between
the reversed first direction and the second; a move next to a pure retraction or a lone Z move
starts or ends at rest. Filament-only moves take |E| / retract speed.
"""

from __future__ import annotations

import numpy as np


def move_times(start: np.ndarray, end: np.ndarray, e: np.ndarray, feed: np.ndarray,
               acceleration: float, junction_deviation: float, retract_speed: float) -> np.ndarray:
    """Seconds per move.

    Parameters
    ----------
    start, end : (k, 3) positions, mm; e : (k,) filament, mm; feed : (k,) mm/s.
    """
    d = end - start
    length = np.linalg.norm(d, axis=1)
    moving = length > 1e-9
    u = np.where(moving[:, None], d / np.maximum(length, 1e-12)[:, None], 0.0)
    a = acceleration
    # junction speed between move i − 1 and move i (both moving)
    cos_theta = -np.einsum("kc,kc->k", u[:-1], u[1:])
    sin_half = np.sqrt(np.clip(0.5 * (1.0 - cos_theta), 0.0, 1.0))
    with np.errstate(divide="ignore"):
        v_j = np.sqrt(a * junction_deviation * sin_half / np.maximum(1.0 - sin_half, 1e-12))
    both = moving[:-1] & moving[1:]
    v_j = np.where(both, np.minimum(v_j, np.minimum(feed[:-1], feed[1:])), 0.0)
    v_in = np.concatenate([[0.0], v_j])
    v_out = np.concatenate([v_j, [0.0]])
    v = feed
    d_acc = np.maximum(v ** 2 - v_in ** 2, 0.0) / (2 * a)
    d_dec = np.maximum(v ** 2 - v_out ** 2, 0.0) / (2 * a)
    cruise = d_acc + d_dec <= length
    t_cruise = (v - v_in) / a + (v - v_out) / a + (length - d_acc - d_dec) / np.maximum(v, 1e-12)
    v_peak = np.sqrt(np.maximum(a * length + 0.5 * (v_in ** 2 + v_out ** 2), 0.0))
    v_peak = np.maximum(v_peak, np.maximum(v_in, v_out))
    t_short = np.maximum((2 * v_peak - v_in - v_out) / a, length / np.maximum(v_peak, 1e-12))
    t = np.where(cruise, t_cruise, t_short)
    t = np.where(moving, t, np.abs(e) / retract_speed)
    return t
