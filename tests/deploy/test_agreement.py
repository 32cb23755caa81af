"""∫K, area, the reached rule and the verdict (ribbond.deploy.agreement) against geometry."""

from __future__ import annotations

import numpy as np
import pytest

from ribbond.deploy.agreement import Agreement, reached, surface_area, total_gaussian_curvature, verdict
from ribbond.design import surfaces


def test_total_gaussian_curvature_of_a_sphere_cap_follows_gauss_bonnet():
    # a cap of half-angle θ on a sphere of radius r: ∫K = area / r² = 2π (1 − cos θ)
    for deg in (30.0, 60.0, 90.0):
        V, F = surfaces.sphere_cap(radius=60.0, half_angle_deg=deg, rings=40)
        exact = 2 * np.pi * (1 - np.cos(np.radians(deg)))
        # the interior vertices leave out the outermost ring's half strip: within a ring's share
        ring = 2 * np.pi * np.sin(np.radians(deg)) * np.radians(deg) / 40
        assert total_gaussian_curvature(V, F) == pytest.approx(exact, abs=1.5 * ring)
        assert surface_area(V, F) == pytest.approx(exact * 60.0 ** 2, rel=0.01)


def test_developable_and_saddle_surfaces():
    V, F = surfaces.cylinder_patch()
    assert abs(total_gaussian_curvature(V, F)) < 1e-9
    UV, F = surfaces.grid(10, 10)
    assert total_gaussian_curvature(np.column_stack([UV, 0 * UV[:, 0]]), F) == pytest.approx(0.0, abs=1e-12)
    V, F = surfaces.saddle(rings=20)
    assert total_gaussian_curvature(V, F) < -0.1


def test_bad_shapes_are_refused():
    with pytest.raises(ValueError, match="must be"):
        total_gaussian_curvature(np.zeros((3, 2)), np.array([[0, 1, 2]]))


def _a(mean=1.0, kp=1.0, kt=1.0, area=1.0, spread=(1.0, 1.2)):
    return Agreement(mean_pct=mean, max_pct=3 * mean, curvature_predicted=kp, curvature_target=kt,
                     area_ratio=area, spread_mean=spread, spread_max=(3.0, 3.5))


@pytest.mark.parametrize("a, expected, words", [
    (_a(), True, "will take the target's shape"),
    (_a(kp=0.06 * 4.3, kt=4.3), False, "keeps 6 % of the target's curvature"),
    (_a(kp=-0.09, kt=-1.65), False, "keeps 5 %"),
    (_a(kp=0.02, kt=0.0), True, "will take"),                   # developable: the absolute floor
    (_a(mean=2.5, spread=(2.5, 2.6)), False, "lands 2.5 %"),
    (_a(spread=(1.0, 4.0)), False, "floppy"),                    # a release that lands far counts
    (_a(area=0.8), False, "area is 80 %"),
])
def test_reached_rule_and_verdict(a, expected, words):
    assert reached(a) is expected
    assert words in verdict(a)
    assert verdict(a).startswith("will take" if expected else "will NOT take")
