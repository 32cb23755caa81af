"""The design parameters: one validated model with the paper's defaults (§4.3, §6.1).

``DesignParameters`` is what a user sets (``--params FILE``, the API) and what ``design.json``
records under ``parameters``; ``SolverSettings`` are the engine's numerical knobs, which do not
change the design the method aims at, only how closely and how fast it is reached.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator


def sigma_for_spacing(spacing: float, ribbon_size: float, prestretch: float) -> float:
    """Invert Eq. 10: the stretch σ at which the pattern spacing μ equals ``spacing``.

    μ = r (s − 1) / (s − σ) σ, so σ = μ s / (μ + r (s − 1)), with r = l_r along the ribbons or
    w_r across them.
    """
    return spacing * prestretch / (spacing + ribbon_size * (prestretch - 1.0))


def spacing_for_sigma(sigma: float, ribbon_size: float, prestretch: float) -> float:
    """Eq. 10: the pattern spacing μ = r (s − 1) / (s − σ) σ that yields the average stretch σ."""
    return ribbon_size * (prestretch - 1.0) / (prestretch - sigma) * sigma


class SizeSpec(BaseModel):
    """The physical size of the target surface: its bounding-box diagonal in mm (as the paper)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)
    bbox_diagonal: float = Field(gt=0, description="bounding-box diagonal of the target surface, mm")


class DesignParameters(BaseModel):
    """Everything that defines a design, with the paper's defaults.

    σ maps the target (deployed) surface to the flat (pre-stretched) one, so σ ≥ 1: the flat
    surface is larger. ``sigma2_bounds`` defaults to [1.3, σ2max] with σ2max from Eq. 10 at
    μ2max = l_r (≈ 1.51 for the defaults).
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    prestretch: float = Field(1.6, gt=1.0, description="fabric pre-stretch factor s")
    ribbon_length: float = Field(15.0, gt=0, description="ribbon length l_r, mm")
    ribbon_width: float = Field(1.5, gt=0, description="ribbon width w_r, mm")
    sigma1_bounds: tuple[float, float] = Field((1.0, 1.3), description="stretch bounds along k1")
    sigma2_bounds: tuple[float, float] | None = Field(
        None, description="stretch bounds across k1; default [1.3, σ2max(μ2max = l_r)]")
    smoothing_lambda: float = Field(
        0.0, le=0.0, description="line-field smoothing λ (Table 1): 0 default, negative smooths less; "
        "for the default aligned field in (-1, 0], the relative change of its smoothing length")
    min_ribbon_length: float = Field(2.0, gt=0, description="shorter ribbons are dropped, mm")
    max_trim_angle: float = Field(25.0, gt=0, lt=90, description="trim where a ribbon turns away "
                                  "from the direction field by more than this, degrees")
    size: SizeSpec | None = Field(None, description="physical size; None: the largest that fits the frame "
                             "and the curvature table (the daemon's default; the CLI reads the file's units as mm)")
    printer_profile: str = Field("ultimaker2-tpu", min_length=1)
    curvature_table: str = Field("tpu95a-lycra-default", min_length=1)

    @model_validator(mode="after")
    def _check_bounds(self) -> "DesignParameters":
        s = self.prestretch
        if self.min_ribbon_length > self.ribbon_length:
            # a ribbon is at most ribbon_length long (its staggered segment): all would be dropped
            raise ValueError(f"min_ribbon_length = {self.min_ribbon_length:g} mm: longer than ribbon_length = "
                             f"{self.ribbon_length:g} mm, the longest a ribbon is: every ribbon would be dropped")
        if self.sigma2_bounds is None:
            object.__setattr__(self, "sigma2_bounds", self._default_sigma2())
        for name in ("sigma1_bounds", "sigma2_bounds"):
            lo, hi = getattr(self, name)
            # name what the user sent: a default bound is not a field they set
            given = name in self.model_fields_set
            what = f"{name} = [{lo:g}, {hi:g}]" if given else f"the default {name} = [{lo:g}, {hi:g}]"
            if not 1.0 <= lo <= hi:
                raise ValueError(f"{what}: need 1 <= lower <= upper (the flat surface is the stretched one)")
            if hi >= s:
                raise ValueError(f"{what}: the upper bound must stay below prestretch = {s:g} (Eq. 10 "
                                 "diverges at σ = s)" + ("" if given else f"; set {name} below it"))
        return self

    def _default_sigma2(self) -> tuple[float, float]:
        """[1.3, σ2max] with σ2max from Eq. 10 at μ2max = l_r; refused naming l_r and w_r (the
        fields the user set) when they give no stretch range."""
        length, width, s = self.ribbon_length, self.ribbon_width, self.prestretch
        if not length > width:
            raise ValueError(f"ribbon_length = {length:g} mm, ribbon_width = {width:g} mm: a ribbon must be "
                             "longer than it is wide (the default sigma2_bounds, Eq. 10 at μ2 = ribbon_length, "
                             "has no stretch above 1 otherwise)")
        hi = sigma_for_spacing(length, width, s)
        if not hi < s:
            raise ValueError(f"ribbon_length = {length:g} mm is too long for ribbon_width = {width:g} mm: "
                             f"the default sigma2_bounds reaches prestretch = {s:g}; set sigma2_bounds")
        return (min(1.3, hi), hi)

    @property
    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """((σ1min, σ1max), (σ2min, σ2max))."""
        lo2, hi2 = self.sigma2_bounds or (0.0, 0.0)  # always set by the validator
        return ((self.sigma1_bounds[0], self.sigma1_bounds[1]), (lo2, hi2))


class SolverSettings(BaseModel):
    """Numerical settings of the engine: tolerances, caps and accelerations."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    tolerance: float = Field(1e-6, gt=0, description="stop when the mean change of σ1 and of σ2 is below")
    max_iterations: int = Field(3000, ge=1, description="cap on local/global iterations (the flattening's "
                                "row-count phase and the paper's iteration together)")
    residual_tolerance: float = Field(
        1e-3, ge=0, description="the paper's iteration also stops once the root-mean-square misfit of "
        "Eq. 3, √(E / target area), is at most this and every face's stretches lie within the bounds "
        "to it: the precision the report measures the bounds to (1e-3); 0: only the change of σ stops it")
    local_passes: int = Field(2, ge=1, description="R/Σ alternations per global step (§4.3: twice)")
    anderson_window: int = Field(6, ge=0, description="Anderson acceleration history; 0 turns it off")
    slim_iterations: int = Field(2, ge=0, description="SLIM iterations after the Tutte embedding")
    mid_bounds_iterations: int = Field(
        500, ge=0, description="cap on the first phase, which aims every face at the middle of "
        "the bounds before the bounded iteration (the most uniform flattening); 0 turns it off")
    spacing_integrability_weight: float = Field(
        1e-3, ge=0, description="a phase of the flattening also penalizes the curl of (s − σ2) k2, so "
        "that the rows Eq. 10 asks for can be counted along k1 (θ's frequency integrable), this much "
        "against Eq. 3 (per unit target area); Eq. 3 alone follows it, so the result is a minimizer "
        "of Eq. 3; 0: no such phase (the previous engine)")
    spacing_integrability_iterations: int = Field(
        800, ge=1, description="cap on that coupled phase's iterations (it converges slowly)")
    spacing_integrability_budget: float = Field(
        4e6, gt=0, description="and on its cost: at most this many face-iterations (faces × "
        "iterations, about 3-4 s on one core), but never fewer than 25 iterations")
    stripe_edge_fraction: float = Field(
        0.15, gt=0, le=1, description="the stripe patterns are computed on a triangulation of the flat "
        "surface with edges of this share of the shortest stripe period")
    stripe_spacing_weight: float | None = Field(
        None, gt=0, description="when set, θ's frequency is made integrable along the ribbon direction "
        "first, with this weight on Eq. 10's spacing (smaller: centerlines closer to the field, spacing "
        "further from Eq. 10); unset: Eq. 10's frequency as it is")
    stripe_direction_weight: float = Field(
        0.5, gt=0, description="θ's stripe energy weighs a phase change along the ribbons (their "
        "direction) this many times one across them (their spacing): below 1 the rows keep Eq. 10's "
        "spacing and turn a little instead; 1 is KCPS15's isotropic energy")
    stripe_max_faces: int = Field(
        150_000, ge=100, description="that triangulation is made coarser rather than exceed this many faces")
    coarse_faces: int = Field(
        12_000, ge=0, description="meshes of 4× more faces start from a flattening of a copy "
        "decimated to this many faces (coarse to fine); 0 turns it off")
    line_field: Literal["aligned", "kcps13"] = Field(
        "aligned", description="'aligned': k1 where it is defined, smooth where it is not; 'kcps13': "
        "the previous engine's (A − λB) z = B q with λ in units of the surface scaled to unit area")
    umbilic_tolerance: float = Field(
        0.3, ge=0, lt=1, description="a face is umbilic where the curvature anisotropy "
        "(|κ1| − |κ2|) / (|κ1| + |κ2|) is at most this")
    refine_below_faces: int = Field(
        3_000, ge=0, description="targets with fewer faces (scans, exports) are refined at intake: midpoint "
        "subdivision onto local quadric fits, the file's vertices kept, to at least refine_to_faces "
        "(within max_faces), so that coarse meshes give smooth layouts; 0 turns it off")
    refine_to_faces: int = Field(
        10_000, ge=1, description="the face count a refined target reaches at least (each round × 4 faces)")
    refine_method: Literal["quadric", "smooth"] = Field(
        "quadric", description="how a coarse target is refined (refine_below_faces): 'quadric', midpoint "
        "subdivision onto two-ring quadric fits, the file's vertices kept (the default: best on bumpy "
        "targets and small developable ones); 'smooth', Loop subdivision's limit weights blending "
        "four-ring cubic fits, the file's vertices moved (per-face curvature far closer on noisy scans; "
        "docs/engine.md, 'Coarse targets')")
    max_faces: int = Field(400_000, ge=1, description="meshes with more faces are refused")
    merge_tolerance: float = Field(
        1e-7, ge=0, description="vertices closer than this × bbox diagonal are merged")
    layout_margin: float = Field(
        10.0, ge=0, description="free border kept inside the frame around the flat layout, mm")
    optimize: bool = Field(
        True, description="optimize the ribbons' thicknesses against the predicted deployed shape (stage "
        "optimize, when the shape is predicted); false: the paper's forward design")
    optimize_budget_s: float = Field(
        45.0, gt=0, le=3600, description="wall-time budget of the layout's optimization against the "
        "prediction (stage optimize, the forward layout's prediction included: the ribbons' "
        "thicknesses; ribbond.deploy.optimize), s; the optimized layout's own prediction follows it")


def check_smoothing(params: "DesignParameters", solver: "SolverSettings") -> None:
    """Raise ValueError when ``smoothing_lambda`` is outside what ``solver.line_field`` accepts."""
    if solver.line_field == "aligned" and not params.smoothing_lambda > -1.0:
        raise ValueError(
            f"smoothing_lambda = {params.smoothing_lambda:g}: the aligned line field takes λ in (-1, 0] "
            "(the relative change of its smoothing length; Table 1's -0.01 and -0.1 smooth slightly "
            "less); the previous engine's unbounded λ needs line_field = 'kcps13' under [solver]")


class DesignSettings(BaseModel):
    """What a ``--params`` file holds: the design parameters and, optionally, solver settings."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    parameters: DesignParameters = DesignParameters()
    solver: SolverSettings = SolverSettings()

    @model_validator(mode="after")
    def _smoothing(self) -> "DesignSettings":
        check_smoothing(self.parameters, self.solver)
        return self


def _value(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    return json.dumps(value, default=str, allow_nan=True) if not isinstance(value, str) else repr(value)


def _bounds_text(model: type[BaseModel] | None, field: str) -> str:
    """' > 0', ' in (0, 90)'…: the numeric constraints of ``model.field`` for a message."""
    info = model.model_fields.get(field) if model is not None else None
    parts = []
    for item in (info.metadata if info is not None else []):
        for attr, op in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")):
            bound = getattr(item, attr, None)
            if bound is not None:
                parts.append(f"{op} {bound:g}")
    return (" " + " and ".join(parts)) if parts else ""


#: The model behind each section of the ``--params`` layout, for the constraints a message names.
_MODELS: dict[str, type[BaseModel]] = {"": DesignParameters, "size": SizeSpec, "solver": SolverSettings}


NAME_SHOWN = 64


def _cut(name: str) -> str:
    return name if len(name) <= NAME_SHOWN else name[:NAME_SHOWN] + "…"


def _problem(err: Any, section: str | None) -> str:
    """One pydantic error as ``field = value: what is wrong``, in the user's own field names."""
    # (a key the user sent may be anything: a field name is shown cut to NAME_SHOWN characters)
    loc = [_cut(str(p)) for p in err["loc"] if not isinstance(p, int)]
    index = "".join(f"[{p}]" for p in err["loc"] if isinstance(p, int))   # an element of a bounds pair
    field = ".".join(([section] if section else []) + loc) + index
    kind = err["type"]
    if kind == "missing":
        return f"{field}: required"
    if kind == "extra_forbidden":
        model = _MODELS.get(".".join(([section] if section else []) + loc[:-1]))
        known = ", ".join(model.model_fields) if model is not None else ""
        return f"{field}: unknown setting" + (f" (known: {known})" if known else "")
    if not loc:                                   # a model validator: its message names the fields
        return str(err.get("ctx", {}).get("error") or err["msg"]).removeprefix("Value error, ")
    model = _MODELS.get(".".join(([section] if section else []) + loc[:-1]))
    shown = f"{field} = {_value(err.get('input'))}"
    if kind == "finite_number":
        return f"{shown}: must be a finite number{_bounds_text(model, loc[-1])}"
    return f"{shown}: {err['msg'].removeprefix('Value error, ')}"


class ParameterError(ValueError):
    """Design parameters refused: the message names each field as the user wrote it; ``errors``
    lists them as ``{loc, msg, type}`` (loc in the user's layout, e.g. ``["solver", "tolerance"]``)."""

    def __init__(self, exc: ValidationError, section: str | None) -> None:
        problems = exc.errors(include_url=False)
        super().__init__("; ".join(_problem(err, section) for err in problems))
        self.errors = [{"loc": ([section] if section else []) + list(err["loc"]), "msg": _problem(err, section),
                        "type": err["type"]} for err in problems]


def parameters_from_json(text: str, *, field: str = "parameters", program: bool = False) -> dict[str, Any]:
    """Design parameters sent as JSON text (a form's ``field``), checked only for shape: a JSON
    object, and none at all with a G-code ``program`` (its parameters are a mesh's); the values are
    ``settings_from_dict``'s to check.

    Raises
    ------
    ValueError
        naming ``field``: not JSON, not an object, or parameters given with a program.
    """
    try:
        params: Any = json.loads(text)
    except ValueError as exc:
        raise ValueError(f"{field}: not valid JSON: {exc}") from None
    if not isinstance(params, dict):
        raise ValueError(f"{field}: expected a JSON object of design parameters")
    if program and params:           # said, not silently dropped
        raise ValueError(f"{field}: a G-code program takes no design parameters (they are a mesh's)")
    return params


def settings_from_dict(data: dict[str, Any]) -> DesignSettings:
    """``DesignSettings`` from the ``--params`` layout: design parameters at the top level and an
    optional ``solver`` table.

    Raises
    ------
    ValueError
        naming each offending field as the user wrote it (``ribbon_length = inf: must be a finite
        number > 0``), unknown keys by name, never a derived field.
    """
    if not isinstance(data, dict):
        raise ValueError("expected a table of parameters at the top level")
    data = dict(data)
    solver = data.pop("solver", {})
    if not isinstance(solver, dict):
        raise ValueError(f"solver = {_value(solver)}: expected a table of solver settings")
    try:
        parameters = DesignParameters(**data)
    except ValidationError as exc:
        raise ParameterError(exc, None) from None
    try:
        settings = SolverSettings(**solver)
    except ValidationError as exc:
        raise ParameterError(exc, "solver") from None
    try:
        return DesignSettings(parameters=parameters, solver=settings)
    except ValidationError as exc:
        raise ParameterError(exc, None) from None


def check_printable(params: DesignParameters, frame_size: tuple[float, float], nozzle_diameter: float) -> None:
    """Refuse, before any compile, parameters that can only make a design that prints nothing or
    degenerate geometry on this printer (``frame_size`` mm, ``nozzle_diameter`` mm).

    Raises
    ------
    ValueError
        naming the field the user sent and the printer's dimension it is measured against.
    """
    diagonal = math.hypot(*frame_size)
    frame = f"the printer's frame ({frame_size[0]:g} × {frame_size[1]:g} mm, diagonal {diagonal:.0f} mm)"
    for name in ("ribbon_length", "ribbon_width", "min_ribbon_length"):
        value = getattr(params, name)
        if value > diagonal:
            why = ": every ribbon would be dropped" if name == "min_ribbon_length" else ""
            raise ValueError(f"{name} = {value:g} mm: longer than {frame}{why}")
    if params.ribbon_width < nozzle_diameter:
        raise ValueError(f"ribbon_width = {params.ribbon_width:g} mm: narrower than the printer's nozzle "
                         f"({nozzle_diameter:g} mm)")
    if params.size is not None and params.size.bbox_diagonal < params.ribbon_width:
        raise ValueError(f"size.bbox_diagonal = {params.size.bbox_diagonal:g} mm: smaller than one ribbon "
                         f"width (ribbon_width = {params.ribbon_width:g} mm): the surface cannot hold a ribbon")


def load_settings(path: Path) -> DesignSettings:
    """Read a ``--params`` file (TOML or JSON).

    Top-level keys are design parameters; an optional ``[solver]`` table holds solver settings.

    Raises
    ------
    ValueError
        naming the file and each offending field.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read the parameter file ({exc})") from None
    try:
        data: Any = json.loads(text) if path.suffix.lower() == ".json" else tomllib.loads(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ValueError(f"{path}: not valid {'JSON' if path.suffix.lower() == '.json' else 'TOML'}: {exc}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a table of parameters at the top level")
    try:
        return settings_from_dict(data)
    except ValueError as exc:
        raise ValueError(f"{path}: invalid parameters: {exc}") from None
