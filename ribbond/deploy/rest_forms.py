"""Rest fundamental forms ā and b̄ of the flat surface, from the ribbons as placed.

The homogenized model behind the paper's Eq. 10 (§6.1): where ribbons cover a fraction f_d of a
line along the ribbon direction d and f_p of a line across it, the released fabric there contracts
to c = f + (1 − f)/s in each direction (a motif of length μ1 holding a ribbon of length l_r
contracts to l_r + (μ1 − l_r)/s); bare fabric contracts by 1/s in every direction. The rest
curvature along the ribbons is the side table's κ(τ, μ2) (§5), signed by the side (design-format.md:
front ribbons bulge toward +n, the front = +z of flat.obj), and zero across. In flat Cartesian
coordinates, per face,

    Ā = c_d² d dᵀ + c_p² d⊥ d⊥ᵀ,        B̄ = ±κ c_d² d dᵀ.

Everything is measured from the layout (centerlines, width, thickness, side), never from the
flattening's intended σ:

- the ribbons are rasterized at their real width with flat ends (``coverage_image``);
- at each face centroid, the direction d and the thickness, side and curvature are averages over
  the ribbon centerline samples within a pattern cell's reach (Gaussian weights);
- the measuring lines follow the rows: they are streamlines of the ribbons' own line field
  (``direction_field``: their centerline tangents' tensor, rasterized and smoothed over μ2/2), and
  across, of its normal. A straight line leaves a row that curves in the flat and cuts it at another
  height: concentric rows of radius 30–90 mm read 8.7 % too dense across that way (issue 34);
- f_d is the coverage along the rows over ± μ1 with triangular weights (exact for any
  pattern of period μ1): the nearest centerline's row and the rows μ2 to either side, weighted
  ¼, ½, ¼ (a cell holds a row of each staggered grid); each line may stray sideways by a third of
  μ2, never onto the next row;
- f_p is the coverage across, over ± μ2 with triangular weights, of the union of the ribbons met
  within half a cell (± μ1/2) along the rows: staggered rows each cover w_r of every μ2 (Eq. 10's model);
- f_d and f_p are then smoothed over the nearest faces (Gaussian, σ = μ2/2): the measuring lines
  jump from one row to the next between neighbouring faces.

The windows' lengths come from the nearest ribbon's μ1, μ2 (``Ribbon.spacing``); only the window, not
the measured fraction. The measured μ2 = w_r / f_p enters the table.

No Python loop over faces, vertices or ribbons' points: a loop over sample offsets is all.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
import shapely
from scipy import ndimage
from scipy.spatial import cKDTree

from ribbond.design.format import Ribbon
from ribbond.design.thickness import CurvatureTable, table_curvature

__all__ = ["RibbonSamples", "Coverage", "RestForms", "LayoutRaster", "ribbon_samples", "coverage_image",
           "layout_raster", "face_coverage", "rest_forms", "contraction"]

#: Samples of a ribbon's centerline per pixel of the coverage image.
_SAMPLES_PER_PIXEL = 2.0
#: Largest coverage image, pixels (a 220 × 220 mm frame at 0.25 mm is 775k).
MAX_PIXELS = 2_000_000


@dataclass(frozen=True)
class RibbonSamples:
    """Points along every ribbon's centerline.

    Attributes
    ----------
    xy : (k, 2) positions, mm; tangent : (k, 2) unit tangents; ribbon : (k,) ribbon index;
    end : (k,) 0 inside, −1 the first point, +1 the last point (the flat ends).
    """

    xy: np.ndarray
    tangent: np.ndarray
    ribbon: np.ndarray
    end: np.ndarray


def ribbon_samples(ribbons: Sequence[Ribbon], spacing: float) -> RibbonSamples:
    """Resample every ribbon's polyline every ``spacing`` mm or closer (vectorized over segments)."""
    if not ribbons:
        z = np.zeros((0, 2))
        return RibbonSamples(xy=z, tangent=z, ribbon=np.zeros(0, np.int64), end=np.zeros(0, np.int64))
    pts = [np.asarray(r.points, dtype=float) for r in ribbons]
    counts = np.array([len(p) for p in pts])
    P = np.vstack(pts)
    rid = np.repeat(np.arange(len(ribbons)), counts)
    last = np.cumsum(counts) - 1
    seg = np.ones(len(P), dtype=bool)
    seg[last] = False                                   # a segment starts at every point but the last
    a = P[seg]
    b = P[np.flatnonzero(seg) + 1]
    sr = rid[seg]
    L = np.linalg.norm(b - a, axis=1)
    ok = L > 1e-12
    a, b, sr, L = a[ok], b[ok], sr[ok], L[ok]
    t_hat = (b - a) / L[:, None]
    k = np.maximum(np.ceil(L / spacing).astype(np.int64), 1)
    j = np.arange(k.sum()) - np.repeat(np.cumsum(k) - k, k)
    si = np.repeat(np.arange(len(a)), k)
    xy = a[si] + (j / k[si])[:, None] * (b[si] - a[si])
    tangent = t_hat[si]
    ribbon = sr[si]
    end = np.zeros(len(xy), dtype=np.int64)
    first_seg = np.r_[True, sr[1:] != sr[:-1]]
    end[np.flatnonzero(np.repeat(first_seg, k) & (j == 0))] = -1
    last_seg = np.r_[sr[1:] != sr[:-1], True]
    xy = np.vstack([xy, b[last_seg]])
    tangent = np.vstack([tangent, t_hat[last_seg]])
    ribbon = np.concatenate([ribbon, sr[last_seg]])
    end = np.concatenate([end, np.ones(int(last_seg.sum()), dtype=np.int64)])
    return RibbonSamples(xy=xy, tangent=tangent, ribbon=ribbon, end=end)


@dataclass(frozen=True)
class CoverageImage:
    """A raster of the plastic: ``covered`` and ``inside`` (ny, nx) in [0, 1] with pixel centres at
    origin + (i, j) · pixel (x along columns)."""

    covered: np.ndarray
    inside: np.ndarray
    origin: np.ndarray
    pixel: float

    def sample(self, image: np.ndarray, xy: np.ndarray) -> np.ndarray:
        """Bilinear values of ``image`` at points xy (..., 2); 0 outside the raster (what
        ``scipy.ndimage.map_coordinates(order=1, mode="constant")`` gives, by direct gathers: 1.5× faster;
        a point is inside where clipping leaves it unchanged, and the gathers index shifted views of
        the image: fewer passes over the points, the same arithmetic)."""
        ny, nx = image.shape
        x = ((xy[..., 0] - self.origin[0]) / self.pixel).ravel()
        y = ((xy[..., 1] - self.origin[1]) / self.pixel).ravel()
        xc = np.clip(x, 0, nx - 1)
        yc = np.clip(y, 0, ny - 1)
        inside = xc == x
        inside &= yc == y
        i = xc.astype(np.intp)
        np.minimum(i, nx - 2, out=i)
        j = yc.astype(np.intp)
        np.minimum(j, ny - 2, out=j)
        xc -= i                                                      # the fractions
        yc -= j
        flat = image.ravel()
        k = j * nx
        k += i
        a, b = flat[k], flat[1:][k]
        c, d = flat[nx:][k], flat[nx + 1:][k]
        b -= a
        b *= xc
        a += b                                                       # along x on row j
        d -= c
        d *= xc
        c += d                                                       # along x on row j + 1
        c -= a
        c *= yc
        v = a + c
        v *= inside                                                  # 0 outside (values are ≥ 0)
        return v.reshape(xy.shape[:-1])


@dataclass(frozen=True)
class LayoutRaster:
    """The layout rasterized once over a flat domain: the centerline samples and the coverage image.
    Neither depends on the mesh the coverage is then measured on, so the coarse copy and the
    reference mesh of a prediction (both remeshes of one flat domain) share it.

    Attributes
    ----------
    samples : centerline samples at pixel / 2; tree : their ``cKDTree``; image : the coverage raster;
    ribbon_width : w_r, mm; pixel : the requested raster size, mm (``image.pixel`` may be larger).
    """

    samples: RibbonSamples
    tree: cKDTree
    image: CoverageImage
    ribbon_width: float
    pixel: float


def layout_raster(uv: np.ndarray, F: np.ndarray, ribbons: Sequence[Ribbon], ribbon_width: float, *,
                  pixel: float | None = None) -> LayoutRaster:
    """Rasterize ``ribbons`` (w_r = ``ribbon_width``) over the flat domain of uv (n, 2), F (m, 3).

    pixel : raster size, mm (default w_r / 6).
    """
    if not ribbon_width > 0:
        raise ValueError(f"ribbon_width must be > 0, got {ribbon_width!r}")
    pixel = float(pixel if pixel is not None else ribbon_width / 6.0)
    samples = ribbon_samples(ribbons, pixel / _SAMPLES_PER_PIXEL)
    tree = cKDTree(samples.xy)                         # for the raster and the nearest centerline
    image = coverage_image(samples, ribbon_width, _outline(np.asarray(uv, dtype=float), F), pixel, tree)
    return LayoutRaster(samples=samples, tree=tree, image=image, ribbon_width=float(ribbon_width),
                        pixel=pixel)


def coverage_image(samples: RibbonSamples, width: float, outline: shapely.Geometry, pixel: float,
                   tree: cKDTree | None = None) -> CoverageImage:
    """Rasterize the ribbons (centerline buffered by width/2, flat ends) and the flat domain.

    Parameters
    ----------
    samples : centerline samples at ≤ pixel / 2; width : ribbon width w_r, mm;
    outline : the flat domain; pixel : pixel size, mm; tree : ``cKDTree(samples.xy)`` if made already.
    """
    lo = np.asarray(outline.bounds[:2]) - 2 * pixel
    hi = np.asarray(outline.bounds[2:]) + 2 * pixel
    nx, ny = (np.ceil((hi - lo) / pixel).astype(int) + 1)
    if nx * ny > MAX_PIXELS:
        pixel *= float(np.sqrt(nx * ny / MAX_PIXELS))
        nx, ny = (np.ceil((hi - lo) / pixel).astype(int) + 1)
    gx, gy = np.meshgrid(lo[0] + pixel * np.arange(nx), lo[1] + pixel * np.arange(ny))
    P = np.column_stack([gx.ravel(), gy.ravel()])
    inside = shapely.contains_xy(outline, P[:, 0], P[:, 1]).astype(float)
    covered = np.zeros(len(P))
    if len(samples.xy):
        tree = tree if tree is not None else cKDTree(samples.xy)
        into = np.flatnonzero(inside)                  # outside the domain the coverage is 0 anyway
        dist, idx = tree.query(P[into], distance_upper_bound=0.5 * width + pixel, workers=-1)
        hit = np.isfinite(dist)
        i = idx[hit]
        offset = P[into[hit]] - samples.xy[i]
        tan = samples.tangent[i]
        # anti-aliased: a ramp one pixel wide at the sides and at the flat ends, so that a band of
        # width w covers exactly w whatever the pixel grid
        perp = np.abs(offset[:, 0] * tan[:, 1] - offset[:, 1] * tan[:, 0])
        along = samples.end[i] * np.einsum("kc,kc->k", offset, tan)          # > 0 beyond an end
        side = np.clip((0.5 * width - perp) / pixel + 0.5, 0.0, 1.0)
        ends = np.where(samples.end[i] != 0, np.clip(0.5 - along / pixel, 0.0, 1.0), 1.0)
        covered[into[hit]] = side * ends
    return CoverageImage(covered=(covered * inside).reshape(ny, nx), inside=inside.reshape(ny, nx),
                         origin=lo, pixel=float(pixel))


@dataclass(frozen=True)
class Coverage:
    """What the layout puts on each face of the reference mesh.

    Attributes
    ----------
    direction : (m, 2) unit ribbon direction d (flat coordinates; (1, 0) on bare faces).
    f_along, f_across : (m,) coverage fractions f_d and f_p in [0, 1] (0 on bare faces).
    kappa : (m,) signed rest curvature along d, 1/mm (> 0: toward the front).
    thickness : (m,) mean plastic thickness τ near the face, mm (0 on bare faces).
    mu2 : (m,) measured spacing across, w_r / f_p, mm (inf on bare faces).
    bare : (m,) bool, no ribbon within reach.
    ribbon_weights : (m, R) sparse, the share of ribbon r in face f's weighted means (rows sum to 1,
        zero on bare faces): ``thickness`` is ribbon_weights @ τ, and ``kappa`` the same mean of the
        table's signed κ(τ_r, μ2_f) (``deploy.optimize`` varies τ through it). None when not measured.
    """

    direction: np.ndarray
    f_along: np.ndarray
    f_across: np.ndarray
    kappa: np.ndarray
    thickness: np.ndarray
    mu2: np.ndarray
    bare: np.ndarray
    ribbon_weights: sp.csr_matrix | None = None

    @property
    def area_fraction(self) -> np.ndarray:
        """(m,) share of the face's surroundings under plastic, f_d f_p (exact for a regular pattern)."""
        return self.f_along * self.f_across


def _windows(n: int) -> tuple[np.ndarray, np.ndarray]:
    """n offsets in (−1, 1) and their triangular weights 1 − |t| (midpoint rule)."""
    t = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    return t, 1.0 - np.abs(t)


def face_coverage(uv: np.ndarray, F: np.ndarray, ribbons: Sequence[Ribbon], ribbon_width: float,
                  table: CurvatureTable, *, pixel: float | None = None,
                  n_along: int = 96, n_across: int = 48, raster: LayoutRaster | None = None) -> Coverage:
    """Per-face coverage, direction, thickness and rest curvature measured from the layout.

    Parameters
    ----------
    uv : (n, 2) flat positions, mm; F : (m, 3) faces, counter-clockwise.
    ribbons : the ribbons as placed (front-side print coordinates).
    ribbon_width : w_r, mm; table : the curvature table (κ by side, τ, μ2).
    pixel : raster size, mm (default w_r / 6).
    n_along, n_across : samples of the two measuring lines.
    raster : ``layout_raster`` of these ribbons made once for the flat domain (default: made here
        for the domain of uv, F); it fixes the pixel.
    """
    uv = np.asarray(uv, dtype=float)
    F = np.asarray(F, dtype=np.int64)
    if uv.ndim != 2 or uv.shape[1] != 2:
        raise ValueError(f"uv must have shape (n, 2), got {uv.shape}")
    if not ribbon_width > 0:
        raise ValueError(f"ribbon_width must be > 0, got {ribbon_width!r}")
    m = len(F)
    centroid = uv[F].mean(axis=1)
    if not ribbons:
        return Coverage(direction=np.tile([1.0, 0.0], (m, 1)), f_along=np.zeros(m), f_across=np.zeros(m),
                        kappa=np.zeros(m), thickness=np.zeros(m), mu2=np.full(m, np.inf),
                        bare=np.ones(m, dtype=bool))
    if raster is None:
        raster = layout_raster(uv, F, ribbons, ribbon_width, pixel=pixel)
    elif raster.ribbon_width != ribbon_width or (pixel is not None and pixel != raster.pixel):
        raise ValueError(f"the raster was made for w_r = {raster.ribbon_width} mm, pixel {raster.pixel} mm, "
                         f"not w_r = {ribbon_width} mm, pixel {pixel} mm")
    samples = raster.samples
    mu = np.array([r.spacing for r in ribbons], dtype=float)                 # (R, 2) windows only
    near = _near_ribbons(samples, centroid, mu, raster.pixel)
    d = near.direction
    n = np.column_stack([-d[:, 1], d[:, 0]])
    # the nearest centerline point and its ribbon's windows
    _, i0 = raster.tree.query(centroid, workers=-1)
    c0 = samples.xy[i0]
    mu1_w, mu2_w = mu[samples.ribbon[i0], 0], mu[samples.ribbon[i0], 1]
    field = direction_field(samples, raster.image, 0.5 * float(np.median(mu[:, 1])))
    f_d = _fraction_along(raster.image, field, c0, d, n, mu1_w, mu2_w, n_along)
    f_p = _fraction_across(raster.image, field, centroid, d, n, mu1_w, mu2_w, n_across)
    f_d, f_p = np.clip(f_d, 0.0, 1.0), np.clip(f_p, 0.0, 1.0)
    # the measuring lines jump from row to row between faces: smooth over the nearest faces
    # (Gaussian, σ = μ2 / 2), the scale below which the pattern is not a material
    f_d, f_p = _smooth(centroid, 0.5 * float(np.median(mu[:, 1])), f_d, f_p)
    # thickness, side and the table's curvature at the measured μ2
    mu2 = np.where(f_p > 1e-9, ribbon_width / np.maximum(f_p, 1e-9), np.inf)
    kappa, tau_mean = _rest_curvature(table, ribbons, samples.ribbon[near.sid], near.w, near.wsum, mu2)
    bare = near.bare
    kappa[bare], tau_mean[bare], f_d[bare], f_p[bare] = 0.0, 0.0, 0.0, 0.0
    mu2[bare] = np.inf
    share = np.where(bare[:, None], 0.0, near.w / np.where(bare, 1.0, near.wsum)[:, None])
    weights = sp.csr_matrix((share.ravel(), (np.repeat(np.arange(m), share.shape[1]),
                                             samples.ribbon[near.sid].ravel())), shape=(m, len(ribbons)))
    return Coverage(direction=d, f_along=f_d, f_across=f_p, kappa=kappa, thickness=tau_mean, mu2=mu2,
                    bare=bare, ribbon_weights=weights)


class _Near(NamedTuple):
    """The centerline samples within reach of each face centroid (k per face, Gaussian weights)."""

    sid: np.ndarray          # (m, k) sample ids
    w: np.ndarray            # (m, k) weights, 0 beyond reach
    wsum: np.ndarray         # (m,)
    bare: np.ndarray         # (m,) no sample within reach
    direction: np.ndarray    # (m, 2) the weighted mean direction of the samples' tangents ((1, 0) where bare)


def _near_ribbons(samples: RibbonSamples, centroid: np.ndarray, mu: np.ndarray, pixel: float) -> _Near:
    """The ribbons within reach of each centroid (half a cell along): coarse samples (~1 mm), Gaussian
    weights, and their mean direction (the principal axis of the weighted tangents)."""
    m = len(centroid)
    stride = max(int(round(1.0 / (pixel / _SAMPLES_PER_PIXEL))), 1)
    coarse = np.arange(0, len(samples.xy), stride)
    reach = 0.5 * float(np.median(mu[:, 0]))                                 # half a cell along
    tree = cKDTree(samples.xy[coarse])
    k = min(48, len(coarse))
    dist, idx = tree.query(centroid, k=k, distance_upper_bound=reach, workers=-1)
    dist, idx = dist.reshape(m, k), idx.reshape(m, k)
    near = np.isfinite(dist)
    bare = ~near.any(axis=1)
    safe = np.where(near, idx, 0)
    sid = coarse[safe]                                                       # (m, k) sample ids
    w = np.where(near, np.exp(-0.5 * (np.where(near, dist, 0.0) / (0.5 * reach)) ** 2), 0.0)
    wsum = np.maximum(w.sum(axis=1), 1e-300)
    t = samples.tangent[sid]                                                 # (m, k, 2)
    T = np.einsum("mk,mki,mkj->mij", w, t, t) / wsum[:, None, None]
    _, U = np.linalg.eigh(T)
    d = U[:, :, 1]
    d[bare] = (1.0, 0.0)
    return _Near(sid=sid, w=w, wsum=wsum, bare=bare, direction=d)


@dataclass(frozen=True)
class DirectionField:
    """The ribbons' line field over the flat domain, as a raster of the tensor (cos 2φ, sin 2φ) of their
    centerline tangents, Gaussian-smoothed (σ = ``smoothing``): sign-free, so a ribbon walked either way
    and the two staggered grids add up. ``direction`` reads it at points; ``streamline`` follows it."""

    c2: CoverageImage
    s2: np.ndarray

    def direction(self, xy: np.ndarray, previous: np.ndarray) -> np.ndarray:
        """(k, 2) unit ribbon directions at points xy (k, 2), signed to agree with ``previous`` (k, 2);
        ``previous`` itself where no ribbon is near."""
        a = self.c2.sample(self.c2.covered, xy)
        b = self.c2.sample(self.s2, xy)
        phi = 0.5 * np.arctan2(b, a)
        d = np.column_stack([np.cos(phi), np.sin(phi)])
        d *= np.where(np.einsum("kc,kc->k", d, previous) < 0, -1.0, 1.0)[:, None]
        weak = a * a + b * b < 1e-6
        d[weak] = previous[weak]
        return d

    def streamline(self, start: np.ndarray, d0: np.ndarray, step: np.ndarray, count: int,
                   across: bool = False) -> np.ndarray:
        """(k, count + 1, 2) points every ``step`` (k,) mm from ``start`` (k, 2), the first step along
        ``d0`` (k, 2), following the ribbon direction (``across``: its normal), by the midpoint rule."""
        out = np.empty((len(start), count + 1, 2))
        out[:, 0] = p = start
        prev = d0
        for i in range(count):
            k1 = self._heading(p, prev, across)
            k2 = self._heading(p + (0.5 * step)[:, None] * k1, k1, across)
            p = p + step[:, None] * k2
            out[:, i + 1] = p
            prev = k2
        return out

    def _heading(self, xy: np.ndarray, previous: np.ndarray, across: bool) -> np.ndarray:
        if not across:
            return self.direction(xy, previous)
        prev_d = np.column_stack([previous[:, 1], -previous[:, 0]])            # normal -> its direction
        d = self.direction(xy, prev_d)
        return np.column_stack([-d[:, 1], d[:, 0]])


def direction_field(samples: RibbonSamples, image: CoverageImage, smoothing: float) -> DirectionField:
    """The ribbons' line field on a raster of about smoothing/2 pixels over ``image``'s extent."""
    ny, nx = image.covered.shape
    extent = np.array([nx, ny]) * image.pixel
    pixel = max(0.5 * smoothing, image.pixel)
    n = np.maximum(np.ceil(extent / pixel).astype(int) + 1, 2)
    ij = np.clip(np.rint((samples.xy - image.origin) / pixel).astype(np.int64), 0, n - 1)
    flat = ij[:, 1] * n[0] + ij[:, 0]
    tx, ty = samples.tangent[:, 0], samples.tangent[:, 1]
    c2 = np.bincount(flat, weights=tx * tx - ty * ty, minlength=n[0] * n[1]).reshape(n[1], n[0])
    s2 = np.bincount(flat, weights=2 * tx * ty, minlength=n[0] * n[1]).reshape(n[1], n[0])
    sig = smoothing / pixel
    c2 = ndimage.gaussian_filter(c2, sig, mode="constant")
    s2 = ndimage.gaussian_filter(s2, sig, mode="constant")
    img = CoverageImage(covered=c2, inside=np.ones_like(c2), origin=image.origin, pixel=float(pixel))
    return DirectionField(c2=img, s2=s2)


def _line(field: DirectionField, centre: np.ndarray, d: np.ndarray, half: np.ndarray, n: int,
          across: bool = False) -> np.ndarray:
    """(k, n, 2) the midpoints of n equal pieces of the streamline through ``centre`` over ± ``half``
    (k,): the ribbon direction's (``across``: its normal's), started along ± d."""
    h = 2.0 * half / n
    m = n // 2
    fwd = field.streamline(centre, d, h, m, across)
    bwd = field.streamline(centre, -d, h, n - m, across)
    pts = np.concatenate([bwd[:, ::-1], fwd[:, 1:]], axis=1)                   # n + 1 points, −half..half
    return 0.5 * (pts[:, 1:] + pts[:, :-1])


def _fraction_along(image: CoverageImage, field: DirectionField, c0: np.ndarray, d: np.ndarray,
                    n: np.ndarray, mu1_w: np.ndarray, mu2_w: np.ndarray, n_along: int) -> np.ndarray:
    """f_d: along the rows over ± μ1 (triangular), on the nearest centerline's row and the rows μ2 to
    either side (weights ¼, ½, ¼: both staggered grids of a cell), each line straying ± μ2/3 sideways.
    The lines follow the ribbons' direction field (a row curves in the flat; a straight line leaves it)."""
    m = len(c0)
    ta, wa = _windows(n_along)
    lat = np.linspace(-1.0, 1.0, 5)
    side = field.streamline(c0, n, mu2_w, 1, across=True)[:, 1]                 # the rows μ2 to either side
    other = field.streamline(c0, -n, mu2_w, 1, across=True)[:, 1]
    num = np.zeros(m)
    den = np.zeros(m)
    for start, wr in ((other, 0.25), (c0, 0.5), (side, 0.25)):
        line = _line(field, start, d, mu1_w, n_along)                           # (m, na, 2)
        tang = np.diff(line, axis=1, append=line[:, -1:] + (line[:, -1:] - line[:, -2:-1]))
        tang /= np.maximum(np.linalg.norm(tang, axis=2, keepdims=True), 1e-12)
        nrm = np.stack([-tang[..., 1], tang[..., 0]], axis=-1)
        cov = np.zeros((m, n_along))
        for off in lat:
            p = line + (off * mu2_w / 3.0)[:, None, None] * nrm
            cov = np.maximum(cov, image.sample(image.covered, p))
        ins = image.sample(image.inside, line)
        num += wr * (cov * wa).sum(axis=1)
        den += wr * (ins * wa).sum(axis=1)
    return num / np.maximum(den, 1e-12)


def _fraction_across(image: CoverageImage, field: DirectionField, centroid: np.ndarray, d: np.ndarray,
                     n: np.ndarray, mu1_w: np.ndarray, mu2_w: np.ndarray, n_across: int) -> np.ndarray:
    """f_p: across over ± μ2 (triangular) of the union of the ribbons met within ± μ1/2 along the rows
    (following them: on curved rows a straight shift would meet a row twice, at other heights)."""
    _, wc = _windows(n_across)
    m = len(centroid)
    across = _line(field, centroid, n, mu2_w, n_across, across=True)          # (m, nc, 2)
    start = across.reshape(-1, 2)
    dd = field.direction(start, np.repeat(d, n_across, axis=0))
    reach = np.repeat(0.5 * mu1_w, n_across) / 4.0
    fwd = field.streamline(start, dd, reach, 4)
    bwd = field.streamline(start, -dd, reach, 4)
    pts = np.concatenate([bwd[:, :0:-1], fwd], axis=1)                          # 9 points, −μ1/2..μ1/2
    cov = image.sample(image.covered, pts).max(axis=1).reshape(m, n_across)
    ins = image.sample(image.inside, across)
    return (cov * wc).sum(axis=1) / np.maximum((ins * wc).sum(axis=1), 1e-12)


def _rest_curvature(table: CurvatureTable, ribbons: Sequence[Ribbon], rib: np.ndarray, w: np.ndarray,
                    wsum: np.ndarray, mu2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The weighted means over the nearby samples (their ribbons ``rib`` (m, k)) of the table's signed
    curvature, at each ribbon's thickness and side and the measured μ2, and of the thickness."""
    thick = np.array([r.thickness for r in ribbons])
    sign = np.array([1.0 if r.side == "front" else -1.0 for r in ribbons])
    mu2_tab = np.clip(mu2, table.spacing[0], table.spacing[-1])
    tau = thick[rib]
    mu2k = np.broadcast_to(mu2_tab[:, None], rib.shape).ravel()
    kf = table_curvature(table, "front", tau.ravel(), mu2k).reshape(rib.shape)
    kb = table_curvature(table, "back", tau.ravel(), mu2k).reshape(rib.shape)
    kap = np.where(sign[rib] > 0, kf, -kb)
    return (w * kap).sum(axis=1) / wsum, (w * tau).sum(axis=1) / wsum


def _smooth(points: np.ndarray, sigma: float, *fields: np.ndarray, k: int = 24) -> list[np.ndarray]:
    """Gaussian averages (σ) of per-point ``fields`` over each point's k nearest points."""
    k = min(k, len(points))
    dist, idx = cKDTree(points).query(points, k=k, workers=-1)
    w = np.exp(-0.5 * (dist / sigma) ** 2)
    w /= w.sum(axis=1, keepdims=True)
    return [(w * f[idx]).sum(axis=1) for f in fields]


def _outline(uv: np.ndarray, F: np.ndarray) -> shapely.Geometry:
    """The flat domain as a polygon: the union of the faces. (Not the boundary loop: where two fans
    of faces touch at one boundary vertex, as a fresh triangulation of a curved outline can leave,
    a loop walks only part of the boundary, and the raster then took most of the domain for
    outside: bare fabric.)"""
    poly = shapely.union_all(shapely.polygons(np.asarray(uv, dtype=float)[np.asarray(F, dtype=np.int64)]))
    shapely.prepare(poly)
    return poly


def contraction(f: np.ndarray, prestretch: float) -> np.ndarray:
    """c = f + (1 − f)/s: the length a unit of pre-stretched fabric keeps when released (Eq. 10's model)."""
    if not prestretch > 1:
        raise ValueError(f"prestretch must be > 1, got {prestretch!r}")
    return f + (1.0 - f) / prestretch


@dataclass(frozen=True)
class RestForms:
    """ā and b̄ per face in flat Cartesian coordinates, (m, 2, 2) each."""

    abar: np.ndarray
    bbar: np.ndarray


def rest_forms(coverage: Coverage, prestretch: float) -> RestForms:
    """Ā = c_d² d dᵀ + c_p² d⊥ d⊥ᵀ and B̄ = κ c_d² d dᵀ from the coverage (module docstring)."""
    d = coverage.direction
    n = np.column_stack([-d[:, 1], d[:, 0]])
    cd = contraction(coverage.f_along, prestretch)
    cp = contraction(coverage.f_across, prestretch)
    dd = d[:, :, None] * d[:, None, :]
    nn = n[:, :, None] * n[:, None, :]
    abar = cd[:, None, None] ** 2 * dd + cp[:, None, None] ** 2 * nn
    bbar = (coverage.kappa * cd ** 2)[:, None, None] * dd
    return RestForms(abar=abar, bbar=bbar)
