"""The staggered ribbon layout on the flat surface (§6.1–6.2).

Spacing comes from the final stretches by Eq. 10; two stripe patterns (``stripes``) give the
grid: θ advances across the ribbons with period 2μ2, ψ along them with period μ1. The centerlines of
the two staggered grids are the isolines arg θ = 0 and arg θ = π; along a centerline of grid g the
ribbon midpoints are where arg ψ = gπ. Each ribbon is the piece of its centerline of length l_r
centred on its midpoint (where two midpoints come closer than l_r: cut halfway, a ribbon width
apart), then

- clipped to the flat outline shrunk by half the ribbon width (so the plastic stays on the fabric
  that is kept when the outline is cut),
- trimmed where its centerline turns more than ``max_trim_angle`` from the direction field,
- split where κ1 changes sign (front where κ1 > 0, back elsewhere),
- dropped when shorter than ``min_ribbon_length``.

Where the rows run along the outline (within 30°) and leave the rim bare, a row of Eq. 10's dashes
follows the inset outline and replaces the short chords there (``rim``: the metric along the
outline decides the sheet's total curvature).

Everything is done on arc-length intervals of the centerlines, for all ribbons at once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np
import shapely

from .params import DesignParameters, spacing_for_sigma
from .remesh import locate, remesh_flat
from .rim import RimRibbons, rim_ribbons
from .stripes import (Polylines, StripePattern, StripeSolver, chain_segments, face_areas, integrable_frequency,
                      vertex_average, vertex_line_field)

#: Largest usable stretch as a share of the way from 1 to s: Eq. 10 diverges at σ = s.
_SIGMA_CAP = 0.98




@dataclass(frozen=True)
class StripeGrid:
    """The flat domain (triangulated for the stripes) with the spacing fields and the two patterns.

    Attributes
    ----------
    uv : (n, 2) flat positions, mm; F : (m, 3) faces; parent : (m,) the design face each face lies in.
    mu1, mu2 : (n,) spacing along and across the ribbons at the vertices (Eq. 10), mm.
    kappa1 : (n,) signed curvature along the ribbons at the vertices, 1/mm.
    direction : (m, 2) the ribbon direction k̄1 per face.
    pullback : (m, 2, 2) maps a flat vector (mm, print coordinates) to the target surface, in the
        isometric frame of the design face each face lies in (J⁻¹ of the flattening, or any
        multiple of it: only directions are used);
    k1_target : (m, 2) unit, the target's own k1 (before the line field's smoothing) in that frame:
        the report measures the ribbons' angle to k1 on the target, where they bend and twist
        (the flat map changes angles by up to σ2 / σ1);
    anisotropic : (m,) True where k1 is defined (anisotropy above ``ANISOTROPY_THRESHOLD``).
    theta, psi : the stripe patterns across (period 2μ2) and along (period μ1) the ribbons.
    spacing : the edge length of the stripe mesh, mm.
    """

    uv: np.ndarray
    F: np.ndarray
    parent: np.ndarray
    mu1: np.ndarray
    mu2: np.ndarray
    kappa1: np.ndarray
    direction: np.ndarray
    pullback: np.ndarray
    k1_target: np.ndarray
    anisotropic: np.ndarray
    theta: StripePattern
    psi: StripePattern
    spacing: float

    def mu2_at(self, points: np.ndarray) -> np.ndarray:
        """μ2 (k,) interpolated at ``points`` (k, 2) of the flat domain (nearest face outside it)."""
        face, bary = locate(points, self.uv, self.F)
        return np.einsum("kc,kc->k", bary, self.mu2[self.F[face]])


def face_spacing(sigma: np.ndarray, params: DesignParameters) -> np.ndarray:
    """Eq. 10 per face: (m, 2) μ1 = l_r (s−1)/(s−σ1) σ1 and μ2 = w_r (s−1)/(s−σ2) σ2, mm.

    Stretches are taken within [1, 1 + 0.98 (s − 1)]: below 1 ribbons would overlap, at s the
    spacing is infinite.
    """
    s = params.prestretch
    sig = np.clip(np.asarray(sigma, dtype=float), 1.0, 1.0 + _SIGMA_CAP * (s - 1.0))
    return np.column_stack([spacing_for_sigma(sig[:, 0], params.ribbon_length, s),
                            spacing_for_sigma(sig[:, 1], params.ribbon_width, s)])


def stripe_spacing(shortest_period: float, area: float, edge_fraction: float, max_faces: int) -> float:
    """Edge length of the stripe mesh: ``edge_fraction`` × the shortest period, coarser if the
    domain of ``area`` mm² would need more than ``max_faces`` equilateral faces."""
    h = edge_fraction * shortest_period
    h_cap = np.sqrt(area / (max_faces * np.sqrt(3.0) / 4.0))
    return float(max(h, h_cap))


def stripe_grid(uv: np.ndarray, F: np.ndarray, boundary: np.ndarray, sigma: np.ndarray,
                ribbon_direction: np.ndarray, kappa1: np.ndarray, params: DesignParameters, *,
                pullback: np.ndarray | None = None, k1_target: np.ndarray | None = None,
                anisotropic: np.ndarray | None = None,
                edge_fraction: float = 0.15, max_faces: int = 150_000,
                spacing_weight: float | None = None, direction_weight: float = 1.0) -> StripeGrid:
    """Spacing fields and the θ and ψ stripe patterns on the flat surface (§6.1–6.2).

    Parameters
    ----------
    uv : (n, 2) the flat surface, mm; F : (m, 3) faces, counter-clockwise; boundary : (b,) its
        boundary loop.
    sigma : (m, 2) final principal stretches (σ1 along the ribbons, σ2 across).
    ribbon_direction : (m, 2) unit k̄1 per face; kappa1 : (m,) signed curvature along it, 1/mm.
    pullback : (m, 2, 2) flat (print) vectors to the target face's frame, J⁻¹ up to a scale per
        face (default: identity);
    k1_target : (m, 2) the target's k1 in that frame (default: ``ribbon_direction``);
    anisotropic : (m,) where k1 is defined (default: everywhere); these three only for the report.
    edge_fraction, max_faces : the stripes are computed on a triangulation of the flat domain with
        edges of ``edge_fraction`` × the shortest stripe period (5th percentile), within
        ``max_faces`` faces (``remesh``).
    spacing_weight : when given, θ's frequency is first made as integrable along the ribbon
        direction as this weight of Eq. 10's spacing allows (``stripes.integrable_frequency``):
        centerlines closer to the field, spacing further from Eq. 10. None (default): Eq. 10's
        frequency as it is (KCPS15 as published).
    direction_weight : θ's stripe energy is ∫ (∇φ − ω)ᵀ D (∇φ − ω) with D = n nᵀ + w t tᵀ, t the
        ribbon direction: w < 1 makes a spacing error (across) cost more than a turn (along).
    """
    n = len(uv)
    area = face_areas(uv, F)
    mu = vertex_average(F, face_spacing(sigma, params), area, n)
    k1 = vertex_average(F, kappa1, area, n)
    # the shortest period that matters: a few vertices at the clamps do not set the resolution
    shortest = float(min(np.percentile(mu[:, 0], 5), 2 * np.percentile(mu[:, 1], 5)))
    h = stripe_spacing(shortest, float(area.sum()), edge_fraction, max_faces)
    mesh = remesh_flat(uv, F, boundary, h)
    mu_r, k1_r = mesh.vertex_values(mu), mesh.vertex_values(k1)
    direction = ribbon_direction[mesh.parent]
    X1 = vertex_line_field(mesh.F, direction, face_areas(mesh.uv, mesh.F), len(mesh.uv))
    X2 = np.column_stack([-X1[:, 1], X1[:, 0]])
    solver = StripeSolver(mesh.uv, mesh.F)
    nu_theta = 2 * np.pi / (2 * mu_r[:, 1])
    if spacing_weight is not None:
        nu_theta = np.clip(integrable_frequency(solver, X2, nu_theta, spacing_weight),
                           0.5 * nu_theta, 2.0 * nu_theta)
    theta = solver.solve(X2, nu_theta, ratio=direction_weight,
                         face_direction=direction)     # a phase change along the ribbons turns them
    psi = solver.solve(X1, 2 * np.pi / mu_r[:, 0])
    back = np.broadcast_to(np.eye(2), (len(F), 2, 2)) if pullback is None else np.asarray(pullback)
    k1_t = (ribbon_direction if k1_target is None else k1_target)[mesh.parent]
    aniso = np.ones(len(mesh.F), dtype=bool) if anisotropic is None else np.asarray(anisotropic)[mesh.parent]
    return StripeGrid(uv=mesh.uv, F=mesh.F, parent=mesh.parent, mu1=mu_r[:, 0], mu2=mu_r[:, 1],
                      kappa1=k1_r, direction=direction, pullback=back[mesh.parent], k1_target=k1_t,
                      anisotropic=aniso,
                      theta=theta, psi=psi, spacing=h)


# ---------------------------------------------------------------------------------------------
# ribbons


@dataclass(frozen=True)
class RibbonLayout:
    """The ribbons and the layout checks.

    Attributes
    ----------
    points : one (k_r, 2) polyline per ribbon, mm, flat (front-side print) coordinates.
    grid : (R,) 0 or 1, the staggered grid of each ribbon.
    kappa1 : (R,) mean signed curvature along each ribbon, 1/mm (never changes sign along it).
    spacing : (R, 2) mean (μ1, μ2) along each ribbon, mm.
    length : (R,) mm.
    dropped_short, trimmed_angle : ribbons dropped for length, ribbons trimmed for direction.
    direction_deviation : (q,) angle between ribbon segments and the direction field, degrees,
        with ``direction_weight`` (q,) their lengths.
    k1_deviation : (p,) angle between ribbon segments on faces where k1 is defined and the
        target's own k1 there, degrees, with ``k1_weight`` (p,) their lengths.
    spacing_error_across, spacing_error_along : relative spacing errors (fractions): from each
        ribbon midpoint along its normal to the next centerline against the harmonic mean of μ2
        over that gap (``across_spacing``), and between neighbouring midpoints against μ1.
    centerlines : per grid, the centerline polylines (list of (k, 2) arrays).
    rim, rim_replaced : the last ``rim`` ribbons are the rows along the outline (``rim``), which replaced
        ``rim_replaced`` of the pattern's.
    """

    points: list[np.ndarray]
    grid: np.ndarray
    kappa1: np.ndarray
    spacing: np.ndarray
    length: np.ndarray
    dropped_short: int
    trimmed_angle: int
    direction_deviation: np.ndarray
    direction_weight: np.ndarray
    k1_deviation: np.ndarray
    k1_weight: np.ndarray
    spacing_error_across: np.ndarray
    spacing_error_along: np.ndarray
    centerlines: tuple[list[np.ndarray], list[np.ndarray]]
    rim: int = 0
    rim_replaced: int = 0

    @property
    def count(self) -> int:
        return len(self.points)

    @property
    def front(self) -> np.ndarray:
        """(R,) True for ribbons printed on the front (κ1 > 0)."""
        return self.kappa1 > 0


@dataclass(frozen=True)
class _Centerlines:
    """The centerlines of one grid, concatenated, with arc length running on across polylines."""

    xy: np.ndarray          # (K, 2) nodes
    s: np.ndarray           # (K,) arc length, with a gap before each polyline
    poly: np.ndarray        # (K,) polyline of each node
    link_face: np.ndarray   # (K,) face of the link to the next node, −1 at a polyline's end
    mid_range: np.ndarray   # (P, 2) where midpoints of each polyline may lie (the middle copy of a loop)
    start: np.ndarray       # (P,) first node of each polyline
    closed_length: np.ndarray  # (P,) the loop length for loops, inf for open polylines
    edge: np.ndarray        # (K,) mesh edge of each node
    t: np.ndarray           # (K,) position along it


def _unroll(pl: Polylines) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Node order with loops walked three times (so ribbons may straddle a loop's start).

    Returns the nodes, their polyline, the link faces and, per polyline, the copy count.
    """
    counts = np.diff(pl.offsets)
    copies = np.where(pl.closed, 3, 1)
    # a loop of k + 1 nodes (first repeated) walked three times has 3k + 1 nodes
    new_counts = np.where(pl.closed, 3 * (counts - 1) + 1, counts)
    poly = np.repeat(np.arange(pl.count), new_counts)
    new_off = np.concatenate([[0], np.cumsum(new_counts)])
    local = np.arange(new_off[-1]) - new_off[poly]
    period = np.where(pl.closed, counts - 1, counts)[poly]
    src = pl.offsets[poly] + np.where(pl.closed[poly], local % np.maximum(period, 1), local)
    last = local == new_counts[poly] - 1
    src = np.where(last & pl.closed[poly], pl.offsets[poly], src)
    nodes = pl.nodes[src]
    link_face = pl.link_face[src]
    link_face[last] = -1
    return nodes, poly, link_face, copies


def _centerlines(theta: StripePattern, level: float, gap: float) -> _Centerlines:
    iso = theta.isolines(level)
    pl = chain_segments(len(iso.points), iso.segments, iso.segment_face)
    nodes, poly, link_face, copies = _unroll(pl)
    xy = iso.points[nodes]
    seg = np.zeros(len(nodes))
    same = poly[1:] == poly[:-1]
    seg[1:] = np.where(same, np.linalg.norm(xy[1:] - xy[:-1], axis=1), gap)
    s = np.cumsum(seg)
    P = pl.count
    first = np.searchsorted(poly, np.arange(P))
    last = np.searchsorted(poly, np.arange(P), side="right") - 1
    total = s[last] - s[first] if P else np.zeros(0)
    loop_len = np.where(pl.closed, total / np.maximum(copies, 1), np.inf)
    lo = np.where(pl.closed, s[first] + loop_len, s[first])
    hi = np.where(pl.closed, s[first] + 2 * loop_len, s[last])
    return _Centerlines(xy=xy, s=s, poly=poly, link_face=link_face,
                        mid_range=np.column_stack([lo, hi]) if P else np.zeros((0, 2)),
                        start=first, closed_length=loop_len, edge=iso.edge[nodes], t=iso.t[nodes])


def _on_edges(values: np.ndarray, edges: np.ndarray, edge: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Vertex ``values`` (n,) linearly interpolated at points ``t`` along mesh ``edge``."""
    i, j = edges[edge, 0], edges[edge, 1]
    return (1.0 - t) * values[i] + t * values[j]


def _midpoints(c: _Centerlines, psi: StripePattern, X1: np.ndarray, level: float) -> np.ndarray:
    """Arc lengths (sorted) where the phase of ψ, oriented along the walk, passes ``level`` upward."""
    if len(c.s) < 2:
        return np.zeros(0)
    phase = psi.phase_on_edges(c.edge, c.t)
    # orient each node's phase along the walk: the phase is in the orientation X_i of the edge's low vertex
    walk = np.zeros_like(c.xy)
    same_next = np.append(c.poly[1:] == c.poly[:-1], False)
    same_prev = np.insert(c.poly[1:] == c.poly[:-1], 0, False)
    nxt = np.where(same_next, np.arange(len(c.s)) + 1, np.arange(len(c.s)))
    prv = np.where(same_prev, np.arange(len(c.s)) - 1, np.arange(len(c.s)))
    walk = c.xy[nxt] - c.xy[prv]
    low = psi.topology.edges[c.edge, 0]
    phase = np.where(np.einsum("kc,kc->k", X1[low], walk) < 0, -phase, phase)
    step = np.angle(np.exp(1j * (phase[1:] - phase[:-1])))
    step = np.where(same_next[:-1], step, 0.0)
    # cumulative phase restarting at each polyline's first node
    cum = np.concatenate([[0.0], np.cumsum(step)])
    restart = np.flatnonzero(~same_prev)
    base = phase[restart] - cum[restart]
    Phi = cum + np.repeat(base, np.diff(np.append(restart, len(cum))))
    a, b = Phi[:-1], Phi[1:]
    up = same_next[:-1] & (b > a)
    k_lo = np.floor((a - level) / (2 * np.pi)).astype(np.int64) + 1
    k_hi = np.floor((b - level) / (2 * np.pi)).astype(np.int64)
    count = np.where(up, np.maximum(k_hi - k_lo + 1, 0), 0)
    link = np.repeat(np.arange(len(a)), count)
    off = np.concatenate([[0], np.cumsum(count)])
    k = k_lo[link] + (np.arange(off[-1]) - off[link])
    L = level + 2 * np.pi * k
    frac = (L - a[link]) / (b[link] - a[link])
    s_mid = c.s[link] + frac * (c.s[link + 1] - c.s[link])
    lo, hi = c.mid_range[c.poly[link], 0], c.mid_range[c.poly[link], 1]
    keep = (s_mid >= lo) & (s_mid < hi) if len(c.mid_range) else np.zeros(len(s_mid), dtype=bool)
    return np.sort(s_mid[keep])


#: The longest dash, × l_r: where the pattern's period exceeds μ1 (or a row's short end cell joins its
#: neighbour) a dash f · period is longer than l_r, up to this.
MAX_DASH = 1.25
#: The shortest gap between two dashes of a row, × w_r: closer, the printed ends fuse.
DASH_GAP = 0.5

#: Ribbon polylines are simplified within this distance, mm: the isoline crossings are dense (one per
#: stripe-mesh edge, some a few µm apart), far denser than a printer resolves.
SIMPLIFY_TOLERANCE = 0.005


def _simplified(xy: np.ndarray, owner: np.ndarray) -> list[np.ndarray]:
    """The polylines ``xy`` (k, 2) (``owner`` (k,) their index, ascending), each simplified
    (Douglas–Peucker within ``SIMPLIFY_TOLERANCE``), as a list of arrays."""
    lines = shapely.simplify(shapely.linestrings(xy, indices=owner), SIMPLIFY_TOLERANCE, preserve_topology=False)
    coords, index = shapely.get_coordinates(lines, return_index=True)
    return np.split(coords, np.flatnonzero(np.diff(index)) + 1)


def _weighted_quantiles(values: np.ndarray, weights: np.ndarray, q: tuple[float, ...]) -> list[float]:
    """Quantiles of ``values`` weighted by ``weights`` (0 for empty input)."""
    if len(values) == 0 or np.sum(weights) <= 0:
        return [0.0 for _ in q]
    order = np.argsort(values)
    v, w = values[order], weights[order]
    cw = np.cumsum(w) - 0.5 * w
    cw /= np.sum(w)
    return [float(np.interp(qq, cw, v)) for qq in q]


def ribbon_quantiles(layout: RibbonLayout) -> dict[str, dict[str, float]]:
    """The report's distributions: direction deviation (degrees) and spacing error (%)."""
    dev = _weighted_quantiles(layout.direction_deviation, layout.direction_weight, (0.5, 0.95))
    out: dict[str, dict[str, float]] = {"direction_deviation_deg": {"median": dev[0], "p95": dev[1]}}
    k1 = _weighted_quantiles(layout.k1_deviation, layout.k1_weight, (0.5, 0.95))
    total = float(np.sum(layout.k1_weight))
    if total > 0:       # else no ribbon lies where k1 is defined: nothing to deviate from
        out["ribbon_k1_deviation_deg"] = {
            "median": k1[0], "p95": k1[1], "mean": float(np.sum(layout.k1_deviation * layout.k1_weight) / total)}
    for key, errs in (("spacing_error_pct", np.concatenate([layout.spacing_error_across,
                                                            layout.spacing_error_along])),
                      ("spacing_error_across_pct", layout.spacing_error_across),
                      ("spacing_error_along_pct", layout.spacing_error_along)):
        qs = np.percentile(100 * errs, [50, 95]) if len(errs) else [0.0, 0.0]
        out[key] = {"median": float(qs[0]), "p95": float(qs[1])}
    return out


#: Samples of μ2 along a gap for its harmonic mean; gaps longer than this many μ2 are not gaps.
_GAP_SAMPLES = 8
_GAP_REACH = 3.0


def across_spacing(midpoints: np.ndarray, tangents: np.ndarray, own_line: np.ndarray,
                   centerlines: list[np.ndarray], mu2_at: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Relative error of the spacing across the ribbons, measured as with a ruler.

    From each ribbon midpoint, both ways along the centerline's normal, to the first other
    centerline (of either grid: the staggered grids alternate, μ2 apart); the gap d is compared with
    the harmonic mean H of μ2 over it: the spacing Eq. 10 asks for there, as the phase of θ must
    advance by π over the gap (∫ ds / μ2 = 1 ⇔ d = H). μ2 can change a lot inside one gap, so μ2
    at either end is the wrong reference.

    Parameters
    ----------
    midpoints : (R, 2); tangents : (R, 2) the centerline's direction there; own_line : (R,) the
        index in ``centerlines`` of each midpoint's own centerline.
    centerlines : polylines (k, 2) of both grids; mu2_at : μ2 at points (k, 2) -> (k,).

    Returns
    -------
    (q,) |d − H| / H for every direction that meets a centerline within ``_GAP_REACH`` μ2.
    """
    lines = [line for line in centerlines if len(line) >= 2]
    index = np.array([k for k, line in enumerate(centerlines) if len(line) >= 2], dtype=np.int64)
    if len(midpoints) == 0 or len(lines) == 0:
        return np.zeros(0)
    normal = np.column_stack([-tangents[:, 1], tangents[:, 0]])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    mu = mu2_at(midpoints)
    p = np.concatenate([midpoints, midpoints])
    n = np.concatenate([normal, -normal])
    reach = _GAP_REACH * np.concatenate([mu, mu])
    own = np.concatenate([own_line, own_line])
    rays = shapely.linestrings(np.stack([p, p + reach[:, None] * n], axis=1))
    tree = shapely.STRtree([shapely.LineString(line) for line in lines])
    ray, hit = tree.query(rays, predicate="intersects")
    pts = shapely.intersection(rays[ray], tree.geometries[hit])
    coords, which = shapely.get_coordinates(pts, return_index=True)
    ray_of, line_of = ray[which], index[hit[which]]
    dist = np.einsum("kc,kc->k", coords - p[ray_of], n[ray_of])
    # the own centerline passes through the midpoint; further along the ray it may come back
    valid = (dist > 1e-6) & ((line_of != own[ray_of]) | (dist > 0.5 * reach[ray_of] / _GAP_REACH))
    gap = np.full(len(p), np.inf)
    np.minimum.at(gap, ray_of[valid], dist[valid])
    found = np.isfinite(gap)
    if not found.any():
        return np.zeros(0)
    t = (np.arange(_GAP_SAMPLES) + 0.5) / _GAP_SAMPLES
    samples = p[found][:, None, :] + (gap[found][:, None] * t[None, :])[..., None] * n[found][:, None, :]
    mu_s = mu2_at(samples.reshape(-1, 2)).reshape(-1, _GAP_SAMPLES)
    harmonic = 1.0 / np.mean(1.0 / mu_s, axis=1)
    return np.abs(gap[found] - harmonic) / harmonic


@dataclass
class _Cuts:
    """The ribbons cut so far, grid by grid, with what the layout's checks measure on them."""

    points: list[np.ndarray] = field(default_factory=list)
    grids: list[np.ndarray] = field(default_factory=list)
    kappas: list[np.ndarray] = field(default_factory=list)
    spacings: list[np.ndarray] = field(default_factory=list)
    lengths: list[np.ndarray] = field(default_factory=list)
    deviation: list[np.ndarray] = field(default_factory=list)
    deviation_weight: list[np.ndarray] = field(default_factory=list)
    k1_deviation: list[np.ndarray] = field(default_factory=list)
    k1_weight: list[np.ndarray] = field(default_factory=list)
    along: list[np.ndarray] = field(default_factory=list)
    mids_xy: list[np.ndarray] = field(default_factory=list)
    mids_tangent: list[np.ndarray] = field(default_factory=list)
    mids_line: list[np.ndarray] = field(default_factory=list)
    dropped: int = 0
    trimmed: int = 0


@dataclass(frozen=True)
class _Intervals:
    """A grid's centerlines cut at every breakpoint into arc-length intervals [lo, hi].

    r : the ribbon each interval's middle falls in (−1 before the first); vec, face : the link it lies
    on and that link's face; cosang : |cos| of its angle to the direction field; keep : in a ribbon,
    on a polyline, inside the inset outline and aligned; positive : κ1 > 0 there; trimmed : how many
    ribbons lose an interval for its angle.
    """

    lo: np.ndarray
    hi: np.ndarray
    r: np.ndarray
    vec: np.ndarray
    face: np.ndarray
    cosang: np.ndarray
    keep: np.ndarray
    positive: np.ndarray
    trimmed: int


@dataclass(frozen=True)
class _Pieces:
    """Runs of kept intervals with one ribbon and one sign.

    A, B : where the long enough ones start and end (arc length); start_q : the first interval of
    every run; kept : the indices of the long enough runs; kept_interval : the intervals in them;
    dropped : how many runs were too short.
    """

    A: np.ndarray
    B: np.ndarray
    start_q: np.ndarray
    kept: np.ndarray
    kept_interval: np.ndarray
    dropped: int


class _Midpoints(NamedTuple):
    """The ribbon midpoints of one grid: arc length s (sorted), polyline, and whether ψ put it there
    (False: one more period past a row's first or last, ``_continued``)."""

    s: np.ndarray
    pid: np.ndarray
    real: np.ndarray


def _continued(c: _Centerlines, s_mid: np.ndarray, mu1: np.ndarray, min_length: float) -> _Midpoints:
    """ψ's midpoints, and more wherever a row holds none for a period: in a gap between two of them
    (ψ's phase stalls near its singularities), past a row's first and last (a row continues to its
    end), and along a row where ψ marks none at all (the rows around a saddle's centre): every μ1.
    Rows without them were left bare. Loops only get their gaps filled (they have no ends)."""
    at = lambda s: np.interp(s, c.s, mu1)                                      # noqa: E731
    pid = c.poly[np.clip(np.searchsorted(c.s, s_mid, side="right") - 1, 0, len(c.s) - 1)]
    lo, hi = c.mid_range[:, 0], c.mid_range[:, 1]
    open_ = ~np.isfinite(c.closed_length)
    same = pid[1:] == pid[:-1]
    gap = np.diff(s_mid)
    n_in = np.where(same, np.maximum(np.round(gap / at(s_mid[:-1] + 0.5 * gap)) - 1, 0), 0).astype(np.int64)
    k = np.arange(n_in.sum()) - np.repeat(np.cumsum(n_in) - n_in, n_in)
    inner = np.repeat(s_mid[:-1], n_in) + np.repeat(gap / (n_in + 1), n_in) * (k + 1)
    first = np.insert(~same, 0, True)[:len(pid)] & open_[pid]
    last = np.append(~same, True)[:len(pid)] & open_[pid]
    ends = [_every_period(s_mid[first], lo[pid[first]], -at(s_mid[first])),
            _every_period(s_mid[last], hi[pid[last]], at(s_mid[last]))]
    empty = np.setdiff1d(np.flatnonzero(open_ & (hi - lo >= min_length)), pid)
    n_e = np.maximum(np.round((hi - lo)[empty] / at(0.5 * (lo + hi)[empty])), 1).astype(np.int64)
    j = np.arange(n_e.sum()) - np.repeat(np.cumsum(n_e) - n_e, n_e)
    whole = np.repeat(lo[empty], n_e) + (j + 0.5) * np.repeat((hi - lo)[empty] / n_e, n_e)
    extra = np.concatenate([inner, *ends, whole])
    s = np.concatenate([s_mid, extra])
    poly = c.poly[np.clip(np.searchsorted(c.s, s, side="right") - 1, 0, len(c.s) - 1)]
    poly[:len(s_mid)] = pid
    poly[len(s_mid):len(s_mid) + len(inner)] = np.repeat(pid[:-1], n_in)
    n_end = [len(e) for e in ends]
    poly[len(s_mid) + len(inner):len(s_mid) + len(inner) + sum(n_end)] = np.concatenate(
        [_repeat_owner(pid[first], s_mid[first], lo[pid[first]], -at(s_mid[first])),
         _repeat_owner(pid[last], s_mid[last], hi[pid[last]], at(s_mid[last]))])
    poly[len(s) - len(whole):] = np.repeat(empty, n_e)
    real = np.arange(len(s)) < len(s_mid)
    order = np.lexsort((s, poly))
    return _Midpoints(s=s[order], pid=poly[order], real=real[order])


def _end_count(s0: np.ndarray, bound: np.ndarray, step: np.ndarray) -> np.ndarray:
    """How many more midpoints a period ``step`` apart (signed) fit from s0 toward ``bound``: each one's
    cell (half a period either side) must reach into the row."""
    return np.maximum(np.floor((bound - s0) / step + 0.5), 0).astype(np.int64)


def _every_period(s0: np.ndarray, bound: np.ndarray, step: np.ndarray) -> np.ndarray:
    """The midpoints s0 + j step, j = 1…, toward ``bound`` (``_end_count`` of them per row end)."""
    n = _end_count(s0, bound, step)
    j = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n) + 1
    return np.repeat(s0, n) + j * np.repeat(step, n)


def _repeat_owner(pid: np.ndarray, s0: np.ndarray, bound: np.ndarray, step: np.ndarray) -> np.ndarray:
    return np.repeat(pid, _end_count(s0, bound, step))


def _cells(c: _Centerlines, mids: _Midpoints, mu1_mid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each midpoint's cell [lo, hi] of its row: from the gap centre before it to the one after
    (halfway to its neighbours; a row's first and last cells as long as their neighbour's, or μ1
    alone), within its polyline."""
    s, pid = mids.s, mids.pid
    first_s = c.s[c.start[pid]]
    last_s = c.s[np.append(c.start[1:], len(c.s))[pid] - 1]
    same_prev = np.insert(pid[1:] == pid[:-1], 0, False)
    same_next = np.append(pid[1:] == pid[:-1], False)
    gap_before = np.insert(0.5 * np.diff(s), 0, np.inf)
    gap_after = np.append(0.5 * np.diff(s), np.inf)
    half_before = np.where(same_prev, gap_before, np.where(same_next, gap_after, 0.5 * mu1_mid))
    half_after = np.where(same_next, gap_after, half_before)
    lo = np.maximum(s - half_before, first_s)
    hi = np.minimum(s + half_after, last_s)
    return lo, np.maximum(lo, hi)


def _merge_short_ends(mids: _Midpoints, lo: np.ndarray, hi: np.ndarray, fraction: np.ndarray,
                      min_length: float) -> tuple[np.ndarray, np.ndarray]:
    """A row's end cell too short for a dash (f · length < ``min_length``) joins its neighbour's cell,
    so its share of plastic is printed by the neighbour's dash instead of being lost."""
    lo, hi = lo.copy(), hi.copy()
    pid = mids.pid
    same_prev = np.insert(pid[1:] == pid[:-1], 0, False)
    same_next = np.append(pid[1:] == pid[:-1], False)
    short = fraction * (hi - lo) < min_length
    head = short & ~same_prev & same_next                      # a row's first cell
    tail = short & ~same_next & same_prev                      # its last
    i = np.flatnonzero(head)
    lo[i + 1] = lo[i]
    j = np.flatnonzero(tail)
    hi[j - 1] = hi[j]
    gone = head | tail
    hi[gone] = lo[gone]
    return lo, hi


def _dashes(cells: _Intervals, s_mid: np.ndarray, fraction: np.ndarray, min_gap: float, max_length: float
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The dashes [a, b] of the cells, with the cell of each: one per run of a cell's kept intervals
    (inside the outline, on the field, one sign of κ1), of ``fraction`` (Eq. 10's plastic share along,
    l_r / μ1) of the run's length, placed as near the cell's midpoint as the run allows.

    A whole cell of length P gets f P = l_r where the pattern's period is μ1; a cell cut by the outline,
    a trim, a change of side or the end of its row keeps the same share on what is left (the
    contraction along it is then still 1/σ1, where a dash of l_r would over- or under-fill it), at least
    ``min_gap`` from the run's ends so that dashes never fuse, and at most ``max_length`` long."""
    runs = _pieces(cells, 0.0)
    owner = cells.r[runs.start_q[runs.kept]]
    A, B = runs.A + 0.5 * min_gap, runs.B - 0.5 * min_gap
    D = np.clip(np.minimum(fraction[owner] * (runs.B - runs.A), np.minimum(B - A, max_length)), 0.0, None)
    centre = np.clip(s_mid[owner], A + 0.5 * D, np.maximum(B - 0.5 * D, A + 0.5 * D))
    return centre - 0.5 * D, centre + 0.5 * D, owner


def _breakpoints(c: _Centerlines, k1: np.ndarray, a: np.ndarray, b: np.ndarray,
                 inset: shapely.Geometry) -> np.ndarray:
    """Where the centerlines may be cut: nodes, ribbon ends, where they leave the inset outline, κ1 = 0."""
    li = np.flatnonzero(c.link_face >= 0)
    d_len = c.s[li + 1] - c.s[li]
    sign_change = k1[li] * k1[li + 1] < 0
    zero_s = c.s[li] + d_len * np.where(sign_change, k1[li] / np.where(sign_change, k1[li] - k1[li + 1], 1), 0)
    lines = shapely.linestrings(c.xy, indices=c.poly)
    crossings = shapely.intersection(lines, inset.boundary)
    parts, owner = shapely.get_parts(crossings, return_index=True)
    parts_pts = shapely.get_coordinates(parts)
    n_per_part = shapely.get_num_coordinates(parts)
    cross_owner = np.repeat(owner, n_per_part)
    cross_s = (shapely.line_locate_point(lines[cross_owner], shapely.points(parts_pts))
               + c.s[c.start[cross_owner]]) if len(parts_pts) else np.zeros(0)
    loop = np.isfinite(c.closed_length[cross_owner])    # a walked-thrice loop crosses thrice
    cross_s = np.concatenate([cross_s] + [cross_s[loop] + k * c.closed_length[cross_owner][loop]
                                          for k in (1, 2)])
    return np.unique(np.concatenate([c.s, a, b, zero_s[sign_change], cross_s]))


def _intervals(c: _Centerlines, k1: np.ndarray, a: np.ndarray, b: np.ndarray, inset: shapely.Geometry,
               direction: np.ndarray, cos_trim: float) -> _Intervals:
    """The intervals between breakpoints, what each lies in, and which are kept (see ``_Intervals``)."""
    bp = _breakpoints(c, k1, a, b, inset)
    lo, hi = bp[:-1], bp[1:]
    mid = 0.5 * (lo + hi)
    r = np.searchsorted(a, mid, side="right") - 1
    # no ribbons at all (a row wholly outside the inset outline): no interval lies in one
    in_ribbon = (r >= 0) & (mid < b[np.maximum(r, 0)]) if len(a) else np.zeros(len(mid), dtype=bool)
    has_next = c.link_face >= 0
    link = np.clip(np.searchsorted(c.s, mid, side="right") - 1, 0, len(c.s) - 1)
    on_line = has_next[link] & (c.poly[np.minimum(link + 1, len(c.s) - 1)] == c.poly[link])
    x = np.interp(mid, c.s, c.xy[:, 0])
    y = np.interp(mid, c.s, c.xy[:, 1])
    inside = shapely.contains_xy(inset, x, y)
    vec = c.xy[np.minimum(link + 1, len(c.s) - 1)] - c.xy[link]
    vlen = np.linalg.norm(vec, axis=1)
    face = c.link_face[link]
    fdir = direction[np.maximum(face, 0)]
    cosang = np.abs(np.einsum("kc,kc->k", vec, fdir)) / np.maximum(vlen, 1e-300)
    aligned = cosang >= cos_trim
    positive = np.interp(mid, c.s, k1) > 0
    candidate = in_ribbon & on_line & inside
    return _Intervals(lo=lo, hi=hi, r=r, vec=vec, face=face, cosang=cosang, keep=candidate & aligned,
                      positive=positive, trimmed=len(np.unique(r[candidate & ~aligned])))


def _pieces(iv: _Intervals, min_length: float) -> _Pieces:
    """The runs of kept intervals with one ribbon and one sign, without a break; the short ones dropped."""
    keep, r, positive = iv.keep, iv.r, iv.positive
    brk = np.ones(len(keep), dtype=bool)
    brk[1:] = ~(keep[:-1] & (r[1:] == r[:-1]) & (positive[1:] == positive[:-1]))
    start_q = np.flatnonzero(keep & brk)
    piece = np.cumsum(keep & brk) - 1
    end_q = np.zeros(len(start_q), dtype=np.int64)
    np.maximum.at(end_q, piece[keep], np.flatnonzero(keep))
    A, B = iv.lo[start_q], iv.hi[end_q]
    long_enough = (B - A) >= min_length
    pieces_q = np.flatnonzero(long_enough)
    return _Pieces(A=A[long_enough], B=B[long_enough], start_q=start_q, kept=pieces_q,
                   kept_interval=keep & np.isin(piece, pieces_q), dropped=int(np.sum(~long_enough)))


def _measure_directions(cuts: _Cuts, grid: StripeGrid, iv: _Intervals, kept: np.ndarray) -> None:
    """The kept segments' angles to the direction field, and on the target to its own k1 (where defined)."""
    cuts.deviation.append(np.degrees(np.arccos(np.clip(iv.cosang[kept], 0.0, 1.0))))
    cuts.deviation_weight.append((iv.hi - iv.lo)[kept])
    on_face = np.maximum(iv.face, 0)
    vec_t = np.einsum("kij,kj->ki", grid.pullback[on_face], iv.vec)     # the segment on the target
    cos_k1 = np.abs(np.einsum("kc,kc->k", vec_t, grid.k1_target[on_face])) / np.maximum(
        np.linalg.norm(vec_t, axis=1), 1e-300)
    on_k1 = kept & grid.anisotropic[np.maximum(iv.face, 0)]
    cuts.k1_deviation.append(np.degrees(np.arccos(np.clip(cos_k1[on_k1], 0.0, 1.0))))
    cuts.k1_weight.append((iv.hi - iv.lo)[on_k1])


def _add_pieces(cuts: _Cuts, c: _Centerlines, A: np.ndarray, B: np.ndarray, g: int,
                along: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
    """The pieces' polylines (simplified), lengths and the means of κ1, μ1, μ2 along them."""
    inner_lo = np.searchsorted(c.s, A, side="right")
    inner_hi = np.searchsorted(c.s, B, side="left")
    n_inner = np.maximum(inner_hi - inner_lo, 0)
    counts = n_inner + 2
    off = np.concatenate([[0], np.cumsum(counts)])
    owner_p = np.repeat(np.arange(len(A)), counts)
    local = np.arange(off[-1]) - off[owner_p]
    s_pts = np.where(local == 0, A[owner_p],
                     np.where(local == counts[owner_p] - 1, B[owner_p],
                              c.s[np.minimum(inner_lo[owner_p] + local - 1, len(c.s) - 1)]))
    xy = np.column_stack([np.interp(s_pts, c.s, c.xy[:, 0]), np.interp(s_pts, c.s, c.xy[:, 1])])
    ds = np.diff(s_pts)
    same_piece = owner_p[1:] == owner_p[:-1]
    ds = np.where(same_piece, ds, 0.0)
    length = np.bincount(owner_p[:-1], weights=ds, minlength=len(A))

    def mean_along(values: np.ndarray) -> np.ndarray:
        v = np.interp(s_pts, c.s, values)
        return np.bincount(owner_p[:-1], weights=0.5 * (v[1:] + v[:-1]) * ds,
                           minlength=len(A)) / length

    k1, mu1, mu2 = along
    cuts.kappas.append(mean_along(k1))
    cuts.spacings.append(np.column_stack([mean_along(mu1), mean_along(mu2)]))
    cuts.lengths.append(length)
    cuts.grids.append(np.full(len(A), g))
    cuts.points.extend(_simplified(xy, owner_p))


def _measure_midpoints(cuts: _Cuts, c: _Centerlines, s_mid: np.ndarray, node_of: np.ndarray, pid: np.ndarray,
                       ribbons: np.ndarray, mu1: np.ndarray, first_line: int) -> None:
    """The spacing along between neighbouring kept ribbons, and the kept midpoints for the spacing across."""
    kept_mid = np.zeros(len(s_mid), dtype=bool)
    kept_mid[ribbons] = True
    mu1_mid = np.interp(s_mid, c.s, mu1)
    pair = kept_mid[:-1] & kept_mid[1:] & (pid[1:] == pid[:-1])
    along = np.abs(np.diff(s_mid) - 0.5 * (mu1_mid[1:] + mu1_mid[:-1])) / (0.5 * (mu1_mid[1:] + mu1_mid[:-1]))
    cuts.along.append(along[pair])
    cuts.mids_xy.append(np.column_stack([np.interp(s_mid[kept_mid], c.s, c.xy[:, 0]),
                                         np.interp(s_mid[kept_mid], c.s, c.xy[:, 1])]))
    has_next = c.link_face >= 0
    at = node_of[kept_mid]
    nxt = np.where(has_next[at], at + 1, at)
    prv = np.where(has_next[at], at, np.maximum(at - 1, 0))
    cuts.mids_tangent.append(c.xy[nxt] - c.xy[prv])
    cuts.mids_line.append(first_line + pid[kept_mid])


def _cut_grid(cuts: _Cuts, grid: StripeGrid, c: _Centerlines, g: int, level: float, inset: shapely.Geometry,
              params: DesignParameters, first_line: int) -> None:
    """Cut the ribbons of one staggered grid (centerlines ``c`` at arg θ = ``level``) into ``cuts``."""
    if len(c.s) < 2:
        return
    edges = grid.theta.topology.edges
    k1 = _on_edges(grid.kappa1, edges, c.edge, c.t)
    mu1 = _on_edges(grid.mu1, edges, c.edge, c.t)
    mu2 = _on_edges(grid.mu2, edges, c.edge, c.t)
    s_mid = _midpoints(c, grid.psi, grid.psi.direction, level)
    cos_trim = np.cos(np.deg2rad(params.max_trim_angle))
    mids = _continued(c, s_mid, mu1, params.min_ribbon_length)
    if len(mids.s) == 0:
        return
    mu1_mid = np.interp(mids.s, c.s, mu1)
    fraction = np.clip(params.ribbon_length / mu1_mid, 0.0, 1.0)
    lo, hi = _merge_short_ends(mids, *_cells(c, mids, mu1_mid), fraction, params.min_ribbon_length)
    cells = _intervals(c, k1, lo, hi, inset, grid.direction, cos_trim)
    a, b, owner = _dashes(cells, mids.s, fraction, DASH_GAP * params.ribbon_width,
                          MAX_DASH * params.ribbon_length)
    iv = _intervals(c, k1, a, b, inset, grid.direction, cos_trim)
    cuts.trimmed += cells.trimmed
    pieces = _pieces(iv, params.min_ribbon_length)
    cuts.dropped += pieces.dropped
    if len(pieces.A) == 0:
        return
    _measure_directions(cuts, grid, iv, pieces.kept_interval)
    _add_pieces(cuts, c, pieces.A, pieces.B, g, (k1, mu1, mu2))
    made = np.unique(owner[iv.r[pieces.start_q[pieces.kept]]])
    real = mids.real
    node_of = np.clip(np.searchsorted(c.s, mids.s[real], side="right") - 1, 0, len(c.s) - 1)
    kept_real = np.cumsum(real)[made[real[made]]] - 1                 # indices among the real midpoints
    _measure_midpoints(cuts, c, mids.s[real], node_of, mids.pid[real], kept_real, mu1, first_line)


def _inset(outline: shapely.Polygon, params: DesignParameters) -> shapely.Geometry:
    """Where ribbon centerlines may run: the outline shrunk by half a ribbon width (and the tolerance the
    polylines are simplified within later), so the plastic stays on the fabric kept at the cut."""
    return outline.buffer(-(0.5 * params.ribbon_width + SIMPLIFY_TOLERANCE))


def with_rim(layout: RibbonLayout, grid: StripeGrid, outline: shapely.Polygon, params: DesignParameters,
             short_at: Callable[[np.ndarray], np.ndarray]) -> RibbonLayout:
    """The layout with rows along the outline where the printed plastic falls short along the rows
    (``short_at``, from the realized coverage) and the rows run along a bare rim (``rim``); the
    pattern's chords they replace are dropped. Unchanged when there is no such stretch."""
    inset = _inset(outline, params)
    rim = _rim(grid, inset, layout.points, params, short_at)
    if not rim.points:
        return layout
    kept = np.flatnonzero(~rim.replaced)
    return replace(layout, points=[layout.points[i] for i in kept] + rim.points,
                   grid=np.concatenate([layout.grid[kept], np.zeros(len(rim.points), np.int64)]),
                   kappa1=np.concatenate([layout.kappa1[kept], rim.kappa1]),
                   spacing=np.concatenate([layout.spacing[kept], rim.spacing]),
                   length=np.concatenate([layout.length[kept], rim.length]),
                   rim=len(rim.points), rim_replaced=int(rim.replaced.sum()))


def _rim(grid: StripeGrid, inset: shapely.Geometry, points: list[np.ndarray], params: DesignParameters,
         short_at: Callable[[np.ndarray], np.ndarray]) -> RimRibbons:
    """``rim.rim_ribbons`` with the grid's fields: the direction of the face a point lies in, μ1, μ2
    and κ1 interpolated from its vertices."""
    def at(values: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        def sample(P: np.ndarray) -> np.ndarray:
            face, bary = locate(P, grid.uv, grid.F)
            return np.einsum("kc,kc...->k...", bary, values[grid.F[face]])
        return sample

    def direction_at(P: np.ndarray) -> np.ndarray:
        return grid.direction[locate(P, grid.uv, grid.F)[0]]

    return rim_ribbons(inset, points, direction_at, at(np.column_stack([grid.mu1, grid.mu2])), at(grid.kappa1),
                       params.ribbon_length, params.ribbon_width, params.min_ribbon_length, short_at)


def layout_ribbons(grid: StripeGrid, outline: shapely.Polygon, params: DesignParameters) -> RibbonLayout:
    """Cut the ribbons from the staggered grid (§6.2).

    Parameters
    ----------
    grid : the stripe patterns and fields (``stripe_grid``).
    outline : the flat surface's outline, mm.
    params : ribbon length and width, minimum length, trim angle.
    """
    inset = _inset(outline, params)
    shapely.prepare(inset)
    gap = 10.0 * params.ribbon_length + 1.0
    cuts = _Cuts()
    centerlines: list[list[np.ndarray]] = [[], []]
    for g, level in enumerate((0.0, np.pi)):
        c = _centerlines(grid.theta, level, gap)
        starts = np.append(c.start, len(c.s))
        centerlines[g] = [c.xy[starts[p]:starts[p + 1]] for p in range(len(c.start))]
        _cut_grid(cuts, grid, c, g, level, inset, params, g * len(centerlines[0]))
    across = ([across_spacing(np.concatenate(cuts.mids_xy), np.concatenate(cuts.mids_tangent),
                              np.concatenate(cuts.mids_line), centerlines[0] + centerlines[1], grid.mu2_at)]
              if cuts.mids_xy else [])

    def cat(parts: list[np.ndarray], shape: tuple[int, ...] = (0,)) -> np.ndarray:
        return np.concatenate(parts) if parts else np.zeros(shape)

    return RibbonLayout(points=cuts.points, grid=cat(cuts.grids).astype(np.int64), kappa1=cat(cuts.kappas),
                        spacing=cat(cuts.spacings, (0, 2)), length=cat(cuts.lengths), dropped_short=cuts.dropped,
                        trimmed_angle=cuts.trimmed, direction_deviation=cat(cuts.deviation),
                        direction_weight=cat(cuts.deviation_weight), k1_deviation=cat(cuts.k1_deviation),
                        k1_weight=cat(cuts.k1_weight), spacing_error_across=cat(across),
                        spacing_error_along=cat(cuts.along),
                        centerlines=(centerlines[0], centerlines[1]))
