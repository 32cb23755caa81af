"""deployed.png: a PNG of two 3D views with a colour bar, from the arrays it is given."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image

from ribbond.deploy.picture import render_deployed_png
from ribbond.design import surfaces


def test_renders_a_png_of_both_views():
    V, F = surfaces.cylinder_patch(n_around=12, n_along=6)
    P = V * 1.02
    d = np.linalg.norm(P - V, axis=1)
    png = render_deployed_png(V, F, P, F, d, title="cylinder")
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    img = Image.open(io.BytesIO(png))
    w, h = img.size
    assert w > 2 * h * 0.9 and h >= 400
    rgb = np.asarray(img.convert("RGB")).astype(int)
    # the prediction is coloured (viridis), the target grey: both halves are drawn
    left, right = rgb[:, : w // 2], rgb[:, w // 2:]
    sat = lambda a: (a.max(axis=2) - a.min(axis=2))       # noqa: E731
    assert (sat(right) > 60).mean() > 0.01
    assert ((sat(left) < 12) & (left.mean(axis=2) < 235) & (left.mean(axis=2) > 60)).mean() > 0.01


def test_refuses_a_distance_per_wrong_vertex():
    V, F = surfaces.cylinder_patch(n_around=4, n_along=2)
    with pytest.raises(ValueError, match="distance"):
        render_deployed_png(V, F, V, F, np.zeros(3))
