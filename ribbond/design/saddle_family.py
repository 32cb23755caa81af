"""One family of curvature lines through each ambiguous saddle region (issue 34, §8's limitation).

The paper's line field follows the principal direction of largest |κ| (§4.3). Where a saddle has
|κ1| ≈ |κ2| (K < 0, H ≈ 0: the demo's saddle everywhere) that choice switches between the two
families of curvature lines wherever |κ_max| and |κ_min| cross, and the field turns by 90° there:
the rows make corners, the layout trims and drops ribbons at them, and the printed metric misses the
flattening's. Yet on a saddle the two families are each defined everywhere (κ_max > 0 > κ_min, never
equal), so one of them can run through the whole region without a corner, its rows bending by
about as much as the other's would.

``saddle_family`` finds the ambiguous saddle regions (faces with κ1 κ2 < 0 and an anisotropy at most
the umbilic tolerance, joined across shared edges), picks in each the family that bends more over
it (∫|κ| dA, κ_max's family on a tie) and gives the line field that family's direction with full
weight there. Which field, the paper's or this one, makes the better layout is left to the
prediction (``pipeline.compile``'s stage optimize): this module only proposes it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .curvature import Curvature
from .line_field import interior_edges

__all__ = ["SaddleFamily", "saddle_family"]

#: The paper's field is replaced only where it leaves the chosen family on at least this share of a
#: region's area: below it the two fields (nearly) agree and the alternative is not worth a design.
MIN_SWITCHED_SHARE = 0.1


@dataclass(frozen=True)
class SaddleFamily:
    """The line field's target directions with one family through each ambiguous saddle region.

    Attributes
    ----------
    angle : (m,) the direction to follow in each face's frame, radians (the paper's k1 outside the regions).
    weight : (m,) its data weight in [0, 1] (1 in the regions: the family is well defined there).
    region : (m,) the region of each face, −1 outside every region.
    switched_pct : the share of the regions' area where the family differs from the paper's k1, %.
    """

    angle: np.ndarray
    weight: np.ndarray
    region: np.ndarray
    switched_pct: float


def saddle_family(F: np.ndarray, area: np.ndarray, curvature: Curvature, anisotropy: np.ndarray,
                  tolerance: float, flat_curvature: float) -> SaddleFamily | None:
    """The one-family targets of the line field, or None when no saddle region switches family.

    Parameters
    ----------
    F : (m, 3) faces; area : (m,) their areas.
    curvature : the target's principal curvatures and k1 (``face_curvature``).
    anisotropy : (m,) (|κ1| − |κ2|) / max(|κ1| + |κ2|, κ_flat), the line field's.
    tolerance : faces at or below this anisotropy are ambiguous (the umbilic tolerance).
    flat_curvature : faces with |κ1| + |κ2| below this are flat (their signs are noise), 1/mm.
    """
    F = np.asarray(F, dtype=np.int64)
    k1, k2 = np.asarray(curvature.kappa1, dtype=float), np.asarray(curvature.kappa2, dtype=float)
    a = np.asarray(anisotropy, dtype=float)
    if not (len(k1) == len(k2) == len(a) == len(F) == len(area)):
        raise ValueError(f"curvature, anisotropy and area must have one value per face ({len(F)})")
    ambiguous = (a <= tolerance) & (k1 * k2 < 0) & (np.abs(k1) + np.abs(k2) >= flat_curvature)
    if not ambiguous.any():
        return None
    region = _regions(F, ambiguous)
    k_max, k_min = np.maximum(k1, k2), np.minimum(k1, k2)
    n_regions = int(region.max()) + 1
    inside = region >= 0
    bend_max = np.bincount(region[inside], weights=(area * np.abs(k_max))[inside], minlength=n_regions)
    bend_min = np.bincount(region[inside], weights=(area * np.abs(k_min))[inside], minlength=n_regions)
    use_max = bend_max >= bend_min                                      # per region
    # the paper's k1 is κ_max's direction where κ1 = κ_max; the other family is a quarter turn away
    k1_is_max = k1 >= k2
    follow_max = use_max[np.maximum(region, 0)]
    switched = inside & (k1_is_max != follow_max)
    share = float(area[switched].sum() / area[inside].sum())
    if share < MIN_SWITCHED_SHARE:
        return None
    angle = np.where(switched, np.mod(curvature.angle + 0.5 * np.pi, np.pi), curvature.angle)
    weight = np.where(inside, 1.0, np.clip(a, 0.0, 1.0))
    return SaddleFamily(angle=angle, weight=weight, region=region, switched_pct=100.0 * share)


def _regions(F: np.ndarray, member: np.ndarray) -> np.ndarray:
    """(m,) the connected region (across shared edges) of each member face, −1 for the others."""
    f, g, _ = interior_edges(F)
    both = member[f] & member[g]
    m = len(F)
    graph = sp.coo_matrix((np.ones(int(both.sum())), (f[both], g[both])), shape=(m, m))
    _, label = connected_components(graph, directed=False)
    _, compact = np.unique(label[member], return_inverse=True)
    region = np.full(m, -1, dtype=np.int64)
    region[member] = compact
    return region
