"""A resolved analysis case: every input of a run, defaults included (mm, N, MPa).

Sources, later ones winning: the size table row (geometry/sizes.csv), a case file
(TOML, see cases/05.toml), then command-line options. Every value is checked before any
geometry is built; a bad one raises InputError naming the field and the rule.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Sequence

from geometry.meshspec import MeshSpec
from geometry.table import Dimensions, InputError, lookup, paper_spans, validate

from pipeline.inputs.choices import BEARING_AT, BEARING_SHAPES, MODELS, SOLVERS, SUPPORTS, WANTS
from pipeline.inputs.document import KEYS as DOCUMENT_FIELDS, document_defaults
from pipeline.inputs.tomlfile import read_toml

DIMENSION_KEYS = tuple(f.name for f in fields(Dimensions))
# The inputs a case may give a sensitivity range for ([sensitivity] in a case file, --vary).
SENSITIVITY_KEYS = ("dj", "rf", "seat_inner", "seat_outer", "bearing_centre_mm", "bearing_length_mm")
# The report's title block ([document] in a case file): what the part is, its drawing or
# document number, revision, who made and who checked the calculation.
DOCUMENT_KEYS = DOCUMENT_FIELDS
# The sensitivity ranges of the journal load model's choices (support "bearing" only).
LOAD_MODEL_KEYS = ("bearing_centre_mm", "bearing_length_mm")


def user_text(name: str, text: str) -> str:
    """``text`` (a title-block field, whatever its source: case file or command line) if it
    is printable text on one line, else InputError naming ``name``: a control character (a
    newline, a tab, NUL, an escape) has no place in a report's field."""
    if not text.isprintable():
        raise InputError(f"{name}: a control character in {text!r}; give printable text on one line")
    return text


@dataclass(frozen=True)
class Document:
    """The title block of a run's report, as the case file gives it; a key not given is
    None (a blank field to fill by hand, never an invented value). No effect on any number."""

    part: str | None = None
    number: str | None = None
    revision: str | None = None
    author: str | None = None
    checker: str | None = None

    def as_dict(self) -> dict[str, str | None]:
        return asdict(self)


@dataclass(frozen=True)
class Case:
    """Everything a run needs. Lengths mm, loads N, stresses and moduli MPa."""

    name: str
    size: str
    source: str
    dims: Dimensions
    load_N: float
    E_MPa: float = 210_000.0
    nu: float = 0.3
    allowable_MPa: float = 80.0
    model: str = "quarter"
    support: str = "bearing"
    order: int = 2
    solver: str = "pmg"
    rtol: float = 1e-8
    mesh_factor: float = 1.0
    # The accuracy asked of each wanted peak: its error bar's band at most this percentage of
    # its value (docs/design.md §5, pipeline/analysis/tolerance.py). ``mesh_pinned``: the mesh
    # factor was given (option or case file), so the run never refines past it.
    tolerance_pct: float = 1.0
    mesh_pinned: bool = False
    size_body_mm: float | None = None
    size_feature_mm: float | None = None
    size_fillet_mm: float | None = None
    grading_mm: float | None = None
    approximate_span_mm: float | None = None
    exact_span_mm: float | None = None
    want: str = "both"
    assumed: tuple[str, ...] = field(default_factory=tuple)
    # The journal load model of support "bearing" (docs/design.md §3): the pressure's shape,
    # the loaded length along the journal axis (mm, the side plate's thickness) and the
    # distance from the centre plane x = 0 to the middle of that length (mm). None: the whole
    # journal beyond the fillet, from x = b1/2 + rf to the tip x = b6/2.
    bearing_shape: str = "cosine"
    bearing_length_mm: float | None = None
    bearing_centre_mm: float | None = None
    # (input, low, high) in the input's unit: the ranges the sensitivity analysis uses
    # instead of its defaults, and the user-set inputs it varies (docs/design.md §10).
    sensitivity_ranges: tuple[tuple[str, float, float], ...] = ()
    # The report's title block: results.json's about.document, not an input of the analysis
    # (as_dict leaves it out, so a study variant's key does not depend on it).
    document: Document = field(default_factory=Document)

    def load_model(self) -> dict[str, Any]:
        """What of the journal load a cache key must hold besides the support: the bearing
        pressure's shape and band (mm). Load and E scale a solution; these reshape it."""
        return {"bearing_shape": self.bearing_shape, "bearing_length_mm": self.bearing_length_mm,
                "bearing_centre_mm": self.bearing_centre_mm}

    def bearing_band(self) -> "BearingBand":
        """The loaded band of each journal along x (mm), the defaults resolved."""
        return bearing_band(self.dims, self.bearing_length_mm, self.bearing_centre_mm)

    def mesh_spec(self, factor: float | None = None,
                  hotspots: Sequence[tuple[float, float, float]] = ()) -> MeshSpec:
        """The mesh sizes of this case (defaults scaled to the part), times ``factor``,
        refined around ``hotspots`` (mm; see pipeline.analysis.pilot.pilot)."""
        base = MeshSpec.default_for(self.dims, order=min(self.order, 2))
        # Only the critical peak wanted: the fillet needs no more than the bore edges' size.
        fillet = max(base.size_fillet, base.size_feature) if self.want == "critical" else base.size_fillet
        return replace(
            base,
            size_body=self.size_body_mm or base.size_body,
            size_feature=self.size_feature_mm or base.size_feature,
            size_fillet=self.size_fillet_mm or fillet,
            grading=self.grading_mm or base.grading,
            factor=self.mesh_factor if factor is None else factor,
            hotspots=tuple(tuple(p) for p in hotspots),
        )

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        del out["document"]
        out["dims"] = asdict(self.dims)
        out["assumed"] = list(self.assumed)
        spec = self.mesh_spec()
        out["mesh_sizes_mm"] = {"size_body": spec.size_body, "size_feature": spec.size_feature,
                                "size_fillet": spec.size_fillet, "grading": spec.grading,
                                "size_hotspot": spec.size_hotspot, "size_edge_hotspot": spec.size_edge_hotspot,
                                "hotspot_radius": spec.hotspot_radius,
                                "edge_hotspot_radius": spec.edge_hotspot_radius}
        return out


# Case-file layout: section -> key -> (Case field or "dims.<name>", type).
_NUM = (int, float)
SCHEMA: dict[str, dict[str, tuple[str, tuple[type, ...]]]] = {
    "": {"name": ("name", (str,)), "size": ("size", (str,))},
    "dimensions": {k: (f"dims.{k}", _NUM) for k in DIMENSION_KEYS},
    "load": {"load_N": ("load_N", _NUM)},
    "material": {"E_MPa": ("E_MPa", _NUM), "nu": ("nu", _NUM),
                 "allowable_MPa": ("allowable_MPa", _NUM)},
    "model": {"model": ("model", (str,)), "support": ("support", (str,)), "want": ("want", (str,)),
              "bearing_shape": ("bearing_shape", (str,)), "bearing_length_mm": ("bearing_length_mm", _NUM),
              "bearing_centre_mm": ("bearing_centre_mm", _NUM), "bearing_at": ("bearing_at", (str,))},
    "mesh": {"order": ("order", (int,)), "factor": ("mesh_factor", _NUM), "tolerance_pct": ("tolerance_pct", _NUM),
             "size_body_mm": ("size_body_mm", _NUM), "size_feature_mm": ("size_feature_mm", _NUM),
             "size_fillet_mm": ("size_fillet_mm", _NUM), "grading_mm": ("grading_mm", _NUM)},
    "solver": {"solver": ("solver", (str,)), "rtol": ("rtol", _NUM)},
    "analytic": {"approximate_span_mm": ("approximate_span_mm", _NUM),
                 "exact_span_mm": ("exact_span_mm", _NUM)},
    "sensitivity": {k: (f"sensitivity.{k}", (list,)) for k in SENSITIVITY_KEYS},
    "document": {k: (f"document.{k}", (str,)) for k in DOCUMENT_KEYS},
}


@dataclass(frozen=True)
class BearingBand:
    """The loaded band of a journal along its axis: from ``start_mm`` to ``end_mm``, both
    distances from the centre plane x = 0 (mm); ``whole`` when it is the journal's whole
    bearing surface, from the fillet's end x = b1/2 + rf to the tip x = b6/2."""

    start_mm: float
    end_mm: float
    whole: bool

    @property
    def length_mm(self) -> float:
        return self.end_mm - self.start_mm

    @property
    def centre_mm(self) -> float:
        """Where the band's resultant acts (mm from x = 0): its middle, since the pressure
        is uniform along the journal axis."""
        return (self.start_mm + self.end_mm) / 2


def journal_bearing_surface(d: Dimensions) -> tuple[float, float]:
    """(start, end) of a journal's bearing surface along x (mm): the fillet's end b1/2 + rf
    and the tip b6/2; a loaded band must lie between them."""
    return d.b1 / 2 + d.rf, d.b6 / 2


def bearing_band(d: Dimensions, length_mm: float | None, centre_mm: float | None) -> BearingBand:
    """The loaded band (mm) for a given length and centre, either None: both None, the
    whole bearing surface; a length alone, centred on the bearing surface; a centre alone,
    the longest band centred there that stays on the journal."""
    start, end = journal_bearing_surface(d)
    if length_mm is None and centre_mm is None:
        return BearingBand(start, end, whole=True)
    c = (start + end) / 2 if centre_mm is None else centre_mm
    half = min(c - start, end - c) if length_mm is None else length_mm / 2
    # A band equal to the whole surface (to round-off) is the default model, bit for bit.
    tol = 1e-9 * d.b6
    if abs(c - half - start) <= tol and abs(c + half - end) <= tol:
        return BearingBand(start, end, whole=True)
    return BearingBand(c - half, c + half, whole=False)


# The band --bearing-at puts at a formula's own position unless a length is given: a
# fifth of the journal's bearing length (2.2 mm for No. 05), narrow so that the exact
# formula's tip position is approached within a tenth of that length, and still a few
# facets wide on the default and coarse meshes (docs/design.md §3).
NARROW_BAND_FRACTION = 0.2


def formula_bearing(d: Dimensions, which: str, length_mm: float | None = None,
                    span_mm: float | None = None) -> tuple[float, float]:
    """(centre, length) in mm of the bearing band at a hand formula's own load position
    (docs/design.md §4): half its span, by default the paper's, (b1 + b2)/2 for the
    approximate formula (28.75 mm for No. 05) and b6/2 for the exact one (35 mm, the
    tip). The band goes as near that position as the journal lets it: a band cannot be
    centred on the tip, so there it ends at the tip, centre b6/2 − length/2.
    ``length_mm`` None: the narrow band, NARROW_BAND_FRACTION of the bearing length."""
    if which not in BEARING_AT:
        raise InputError(f"bearing_at: must be one of {', '.join(BEARING_AT)}, got {which!r}")
    start, end = journal_bearing_surface(d)
    length = NARROW_BAND_FRACTION * (end - start) if length_mm is None else length_mm
    span = span_mm if span_mm is not None else _paper_span(d, which)
    return min(max(span / 2, start + length / 2), end - length / 2), length


def formula_bands(case: "Case") -> dict[str, tuple[BearingBand, float]]:
    """Per hand formula, the bearing band at its own load position (formula_bearing, the
    case's spans and bearing length) and that position, half its span (mm)."""
    out = {}
    for which, span in zip(BEARING_AT, (case.approximate_span_mm, case.exact_span_mm)):
        centre, length = formula_bearing(case.dims, which, case.bearing_length_mm, span)
        own = (span if span is not None else _paper_span(case.dims, which)) / 2
        out[which] = (bearing_band(case.dims, length, centre), own)
    return out


def _paper_span(d: Dimensions, which: str) -> float:
    """The paper's span of a formula (mm): b1 + b2 (approximate) or b6 (exact)."""
    return paper_spans(d)[BEARING_AT.index(which)]


def read_case_file(path: Path) -> dict[str, Any]:
    """Flatten a TOML case file into {Case field or 'dims.x': value}, checking keys and types.

    The file is read by pipeline.inputs.tomlfile (regular files of at most 1 MiB, nested
    at most a few levels), the reader study files share."""
    path = Path(path)
    data = read_toml(path, "case")
    flat: dict[str, Any] = {}
    for section, content in data.items():
        if isinstance(content, dict):
            if section not in SCHEMA or section == "":
                raise InputError(f"{section or '[]'}: unknown section in {path}; known: "
                                 f"{', '.join(s for s in SCHEMA if s)}")
            items = [(section, k, v) for k, v in content.items()]
        elif section in SCHEMA and section not in SCHEMA[""]:
            raise InputError(f"{section}: must be a [{section}] section in {path}, got {type(content).__name__}")
        else:
            items = [("", section, content)]
        for sec, key, value in items:
            spec = SCHEMA[sec].get(key)
            where = f"{sec}.{key}" if sec else key
            if spec is None:
                raise InputError(f"{where}: unknown key in {path}; known in [{sec or 'top level'}]: "
                                 f"{', '.join(SCHEMA[sec])}")
            target, types = spec
            if isinstance(value, bool) or not isinstance(value, types):
                raise InputError(f"{where}: expected {' or '.join(t.__name__ for t in types)}, got {value!r}")
            if isinstance(value, int) and abs(value) > 1e300:
                raise InputError(f"{where}: integer too large ({len(str(abs(value)))} digits)")
            flat[target] = value
    return flat


def resolve(size: str | None = None, case_file: Path | None = None,
            overrides: dict[str, Any] | None = None) -> Case:
    """Build and check a Case from a size, a case file and overrides (same keys as the file).

    Overrides use Case field names, or 'dims.<name>' for a dimension. The report's title
    block starts from its defaults file (pipeline.inputs.document), which the case file's
    [document] and the overrides' document fields override.
    """
    values: dict[str, Any] = document_defaults()  # the title block's defaults file, below the case file
    given = {k: v for k, v in (overrides or {}).items() if v is not None}
    if case_file is not None:
        values.update(read_case_file(case_file))
        if size is not None and "size" in values and str(values["size"]) != str(size):
            raise InputError(f"size: --size {size} conflicts with size = \"{values['size']}\" in "
                             f"{case_file}; give one of them")
        _one_position(values)
        if "bearing_at" in given:  # the command line's position replaces the file's
            values.pop("bearing_centre_mm", None)
    _one_position(given)
    values.update(given)
    if size is not None:
        values["size"] = size
    if "size" not in values:
        raise InputError("size: no hook number given (use --size or size = \"05\" in the case file)")
    row = lookup(str(values.pop("size")))
    dim_over = {k.split(".", 1)[1]: float(v) for k, v in list(values.items()) if k.startswith("dims.")}
    for k in list(values):
        if k.startswith("dims."):
            del values[k]
    dims = replace(row.dims, **dim_over)
    ranges = sensitivity_ranges({k: values.pop(k) for k in list(values) if k.startswith("sensitivity.")})
    document = Document(**{k.split(".", 1)[1]: user_text(k, values.pop(k)).strip() or None
                           for k in list(values) if k.startswith("document.")})
    name = values.pop("name", None) or row.size
    load = values.pop("load_N", row.load_N)
    assumed = tuple(k for k in ("dj", "rf", "seat_inner", "seat_outer") if k not in dim_over)
    values.setdefault("mesh_pinned", "mesh_factor" in values)
    at = values.pop("bearing_at", None)
    case = Case(name=str(name), size=row.size, source=row.source, dims=dims, load_N=load,
                assumed=assumed, sensitivity_ranges=ranges, document=document, **values)
    if at is not None and case.support != "bearing":
        raise InputError(f"bearing_at: applies to support = bearing only, got support = {case.support}")
    return check(case if at is None else at_formula_position(check(case), at))


def given_keys(case_file: Path | None = None, overrides: dict[str, Any] | None = None) -> frozenset[str]:
    """The case file's keys (Case fields, "dims.<name>", "sensitivity.<input>",
    "document.<field>") that a case file and the overrides give: what a run must be able to
    use (pipeline.inputs.options.check_options refuses what it cannot)."""
    keys = set(read_case_file(case_file)) if case_file is not None else set()
    return frozenset(keys | {k for k, v in (overrides or {}).items() if v is not None})


def _one_position(values: dict[str, Any]) -> None:
    """InputError if one source (a case file, or the command line) gives both a formula's
    load position (bearing_at) and a bearing centre: they name two positions."""
    if values.get("bearing_at") is not None and values.get("bearing_centre_mm") is not None:
        raise InputError("bearing_at: --bearing-at (bearing_at) sets the bearing centre; give it or "
                         "--bearing-centre (bearing_centre_mm), not both")


def at_formula_position(case: Case, which: str) -> Case:
    """The case with its bearing band's centre (and, unless given, its length) at hand
    formula ``which``'s own load position (:func:`formula_bearing`, the case's spans)."""
    if which not in BEARING_AT:
        raise InputError(f"bearing_at: must be one of {', '.join(BEARING_AT)}, got {which!r}")
    span = case.approximate_span_mm if which == "approximate" else case.exact_span_mm
    centre, length = formula_bearing(case.dims, which, case.bearing_length_mm, span)
    return replace(case, bearing_centre_mm=centre, bearing_length_mm=length)


def sensitivity_ranges(given: dict[str, Any]) -> tuple[tuple[str, float, float], ...]:
    """{'sensitivity.<input>': [low, high]} → ((input, low, high), ...) in the input's unit
    (mm), in SENSITIVITY_KEYS order; InputError unless each is two finite numbers, low <
    high, low >= 0 (a dimension's range; the geometry rules are checked per variant)."""
    out = []
    for name in SENSITIVITY_KEYS:
        v = given.get(f"sensitivity.{name}")
        if v is None:
            continue
        ok = (isinstance(v, (list, tuple)) and len(v) == 2
              and all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v))
        if not ok:
            raise InputError(f"sensitivity.{name}: expected [low, high], two numbers in mm, got {v!r}")
        lo, hi = float(v[0]), float(v[1])
        if not 0 <= lo < hi:
            raise InputError(f"sensitivity.{name}: expected 0 <= low < high (mm), got [{lo:g}, {hi:g}]")
        out.append((name, lo, hi))
    return tuple(out)


def _finite_positive(name: str, v: Any, allow_zero: bool = False) -> None:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InputError(f"{name}: must be a number, got {v!r}")
    if not math.isfinite(v):
        raise InputError(f"{name}: must be finite, got {v!r}")
    if v < 0 or (v == 0 and not allow_zero):
        raise InputError(f"{name}: must be > 0, got {v:g}")


# A band below 0.1 % is below a nodal peak's mesh-to-mesh noise (errorbar.SETTLED, a settled
# peak's band errorbar.SETTLED_BAND): no mesh reaches it; above 50 % the band says nothing.
TOLERANCE_RANGE_PCT = (0.1, 50.0)

# Ranges (N, MPa) outside which the numbers lose meaning in double precision: a load of
# 1e-300 N made a safety factor divide by zero, E = 1e-300 MPa stopped PETSc (error 77).
# They are wide on purpose (the invariance tests scale the part by 1000, its load by 1e6
# and E by 1000); they catch typing errors of many orders of magnitude, not odd designs.
RANGES = {"load_N": (1e-6, 1e15), "E_MPa": (1.0, 1e12), "allowable_MPa": (1e-6, 1e9)}


def _in_range(name: str, v: float) -> None:
    lo, hi = RANGES[name]
    if not lo <= v <= hi:
        raise InputError(f"{name}: must lie in [{lo:g}, {hi:g}], got {v:g}")


def check_spans(case: Case) -> None:
    """The formulas' spans must give them a positive lever arm and put their journal load on
    the journal (docs/design.md §4).

    Approximate method: the reaction's lever l/2 must exceed the bearing load's Dm/pi.
    Exact method: the curved bar needs the reaction outside the ring, l/2 > R = (b1 + di)/4.
    Both: the load's position l/2 lies on the journal's bearing surface, from the fillet's
    end b1/2 + rf to the tip b6/2 (the loaded length the FE model's journal load is put on;
    the paper's spans put it at (b1 + b2)/2 and at the tip). A span beyond it puts the load
    off the part (a 1000 mm span on No. 05's 70 mm part gave 980 MPa).
    """
    d = case.dims
    approx, exact = paper_spans(d)
    l_a = case.approximate_span_mm if case.approximate_span_mm is not None else approx
    l_e = case.exact_span_mm if case.exact_span_mm is not None else exact
    if l_a / 2 <= d.d14 / math.pi:
        raise InputError(f"approximate_span_mm: l/2 = {l_a / 2:g} mm must exceed Dm/pi = "
                         f"{d.d14 / math.pi:.4g} mm (the lever arm of the approximate formula)")
    ring = (d.b1 + d.d2) / 4
    if l_e / 2 <= ring:
        raise InputError(f"exact_span_mm: l/2 = {l_e / 2:g} mm must exceed the ring radius "
                         f"R = (b1 + di)/4 = {ring:.4g} mm (the reactions act outside the ring)")
    start, end = journal_bearing_surface(d)
    tol = 1e-9 * d.b6
    for key, span, given, paper in (("approximate_span_mm", l_a, case.approximate_span_mm, "b1 + b2"),
                                    ("exact_span_mm", l_e, case.exact_span_mm, "b6")):
        half = span / 2
        if not start - tol <= half <= end + tol:
            given = f"{span:g} mm" if given is not None else f"the paper's {paper} = {span:g} mm"
            raise InputError(f"{key}: the span {given} puts the journal load at l/2 = {half:g} mm, off the "
                             f"journal's bearing surface, which runs from the fillet's end b1/2 + rf = {start:g} mm "
                             f"to the tip b6/2 = {end:g} mm; give a span from {2 * start:g} to {2 * end:g} mm")


def check_bearing(case: Case) -> None:
    """The bearing load model must be one of the shapes, and its band must lie on the
    journal, between the fillet's end b1/2 + rf and the tip b6/2 (docs/design.md §3)."""
    if not isinstance(case.bearing_shape, str) or case.bearing_shape not in BEARING_SHAPES:
        raise InputError(f"bearing_shape: must be one of {', '.join(BEARING_SHAPES)}, got {case.bearing_shape!r}")
    length, centre = case.bearing_length_mm, case.bearing_centre_mm
    if length is not None:
        _finite_positive("bearing_length_mm", length)
    if centre is not None:
        _finite_positive("bearing_centre_mm", centre)
    default = case.bearing_shape == "cosine" and length is None and centre is None
    if case.support != "bearing" and not default:
        given = [k for k, v in (("bearing_shape", case.bearing_shape != "cosine"),
                                ("bearing_length_mm", length is not None),
                                ("bearing_centre_mm", centre is not None)) if v][0]
        raise InputError(f"{given}: applies to support = bearing only, got support = {case.support}")
    start, end = journal_bearing_surface(case.dims)
    tol = 1e-9 * case.dims.b6
    where = (f"the journal's bearing surface runs from the fillet's end x = b1/2 + rf = {start:g} mm "
             f"to the tip x = b6/2 = {end:g} mm")
    if length is not None and length > end - start + tol:
        raise InputError(f"bearing_length_mm: must lie in (0, {end - start:g}] mm ({where}), got {length:g}")
    if centre is None:
        return
    if length is None:
        if not start < centre < end:
            raise InputError(f"bearing_centre_mm: must lie strictly between {start:g} and {end:g} mm ({where}), "
                             f"got {centre:g}")
        return
    lo, hi = start + length / 2, end - length / 2
    if not lo - tol <= centre <= hi + tol:
        raise InputError(f"bearing_centre_mm: must lie in [{lo:g}, {hi:g}] mm for a loaded length of {length:g} mm "
                         f"({where}), got {centre:g}")


def check_sensitivity(case: Case) -> None:
    """Each sensitivity range the case gives (``[sensitivity]``, ``--vary``) must be one the
    part allows at both ends: a dimension's end passes the geometry rules
    (geometry.table.validate), a load-model end lies on the journal (:func:`check_bearing`),
    and a load-model range needs the bearing pressure (support "bearing"). An end outside
    them would be analysed as nothing: refused with the rule it breaks."""
    for name, lo, hi in case.sensitivity_ranges:
        model = name in LOAD_MODEL_KEYS
        if model and case.support != "bearing":
            raise InputError(f"sensitivity.{name}: a load-model range applies to support = bearing only, "
                             f"got support = {case.support}")
        for end, v in (("low", lo), ("high", hi)):
            try:
                if model:
                    check_bearing(replace(case, **{name: v}))
                else:
                    validate(replace(case.dims, **{name: v}))
            except InputError as exc:
                raise InputError(f"sensitivity.{name}: the {end} end, {v:g} mm, is outside what the part allows: "
                                 f"{' '.join(str(exc).split())}") from None


# Poisson's ratios from which a nearly incompressible material defeats the element or the
# solver, measured on No. 05 (docs/accuracy.md, "Nearly incompressible material"):
# from NU_P1_LOCKS P1 locks (its peaks fall with nu and its error bar no longer covers the
# P2/P3 value); at NU_ITERATIVE_STALLS the Krylov solvers stop at their 1000-iteration limit
# (P2 with pmg at mesh factor 1.3, P3 at 3) while MUMPS solves them. Between 0.49 and it
# they need hundreds of iterations; a solve that fails there names the material
# (pipeline/fe/solve.py, failure_advice). Above NU_DISPLACEMENT_LIMIT P2 locks too (its
# critical peak reads 5 % high, outside its band, at 0.49999) and MUMPS misses its residual
# check for P2 and P3: this displacement-only model has no answer there.
NU_P1_LOCKS = 0.45
NU_ITERATIVE_STALLS = 0.4999
NU_DISPLACEMENT_LIMIT = 0.4999


def check_incompressibility(case: Case) -> None:
    """Refuse (InputError) an element order or a solver that fails near nu = 0.5: P1 from
    NU_P1_LOCKS (volumetric locking makes its peaks read low, outside their own error bar),
    an iterative solver from NU_ITERATIVE_STALLS (it does not converge). The line says what
    to use instead. Above NU_DISPLACEMENT_LIMIT every order is refused."""
    nu = case.nu
    if nu > NU_DISPLACEMENT_LIMIT:
        raise InputError(f"nu: Poisson's ratio {nu:g} is above {NU_DISPLACEMENT_LIMIT:g}: there P2 locks as well "
                         "and the direct solver misses its residual check; this displacement-only model "
                         f"cannot give an answer (docs/accuracy.md); use nu <= {NU_DISPLACEMENT_LIMIT:g}")
    direct = case.solver == "mumps" or nu < NU_ITERATIVE_STALLS
    if case.order == 1 and nu >= NU_P1_LOCKS:
        instead = "--order 2" + ("" if direct else " --solver mumps")
        raise InputError(f"nu: P1 elements lock at Poisson's ratio {nu:g} (>= {NU_P1_LOCKS:g}, nearly "
                         "incompressible): their peaks read too low, outside their own error bar "
                         f"(docs/accuracy.md); use {instead}")
    if not direct:
        raise InputError(f"nu: at Poisson's ratio {nu:g} (>= {NU_ITERATIVE_STALLS:g}, nearly incompressible) "
                         f"the iterative solver {case.solver} stops at its iteration limit "
                         "(docs/accuracy.md); use --solver mumps")


# A length of the part below this fraction of its tip-to-tip length b6 passes the rules of
# docs/design.md §2 but is extreme: the mesh must resolve it with elements this much smaller
# than the rest, and the stiffness matrix grows ill-conditioned (a seat edge 5e-5 mm from the
# bore stops pmg; a 0.01 mm journal stops MUMPS too). Named when a solve fails.
SMALL_FEATURE = 1e-3


def small_features(dims: Dimensions) -> list[str]:
    """The lengths of the part (mm) below SMALL_FEATURE × b6, smallest first, each named in
    words with its value and its fraction of b6: what a failed solve's line points at."""
    d = dims
    lengths = {
        "the seat's inner edge to the bore, (seat_inner - d2)/2": (d.seat_inner - d.d2) / 2,
        "the seat's outer edge to the body's side, (b1 - seat_outer)/2": (d.b1 - d.seat_outer) / 2,
        "the seat's width, (seat_outer - seat_inner)/2": (d.seat_outer - d.seat_inner) / 2,
        "the ligament beside the bore, (b1 - d2)/2": (d.b1 - d.d2) / 2,
        "the journal diameter dj": d.dj,
        "the journal's bearing length, b2 - rf": d.b2 - d.rf,
        "the fillet's edge to the top and bottom faces, h3/2 - dj/2 - rf": d.h3 / 2 - d.dj / 2 - d.rf,
        "the fillet's edge to the body's sides, b1/2 - dj/2 - rf": d.b1 / 2 - d.dj / 2 - d.rf,
        "the body height h3": d.h3,
        **({"the fillet radius rf": d.rf} if d.rf > 0 else {}),
    }
    small = sorted((v, k) for k, v in lengths.items() if v < SMALL_FEATURE * d.b6)
    return [f"{k} = {v:.3g} mm ({v / d.b6:.1e} of b6 = {d.b6:g} mm)" for v, k in small]


def check(case: Case) -> Case:
    """Return case if every field is usable, else raise InputError for the first bad one."""
    validate(case.dims)
    _finite_positive("load_N", case.load_N)
    _finite_positive("E_MPa", case.E_MPa)
    _finite_positive("allowable_MPa", case.allowable_MPa)
    for k in RANGES:
        _in_range(k, getattr(case, k))
    if isinstance(case.nu, bool) or not isinstance(case.nu, (int, float)) or not (-1 < case.nu < 0.5):
        raise InputError(f"nu: Poisson's ratio must lie in (-1, 0.5), got {case.nu!r}")
    if case.model not in MODELS:
        raise InputError(f"model: must be one of {', '.join(MODELS)}, got {case.model!r}")
    if case.support not in SUPPORTS:
        raise InputError(f"support: must be one of {', '.join(SUPPORTS)}, got {case.support!r}")
    if case.want not in WANTS:
        raise InputError(f"want: must be one of {', '.join(WANTS)}, got {case.want!r}")
    if case.solver not in SOLVERS:
        raise InputError(f"solver: must be one of {', '.join(SOLVERS)}, got {case.solver!r}")
    if isinstance(case.order, bool) or case.order not in (1, 2, 3):
        raise InputError(f"order: element order must be 1, 2 or 3, got {case.order!r}")
    check_incompressibility(case)
    _finite_positive("rtol", case.rtol)
    if case.rtol >= 1e-3:
        raise InputError(f"rtol: solver tolerance must be below 1e-3, got {case.rtol:g}")
    _finite_positive("mesh_factor", case.mesh_factor)
    if not 0.05 <= case.mesh_factor <= 20:
        raise InputError(f"mesh_factor: must lie in [0.05, 20], got {case.mesh_factor:g}")
    _finite_positive("tolerance_pct", case.tolerance_pct)
    if not TOLERANCE_RANGE_PCT[0] <= case.tolerance_pct <= TOLERANCE_RANGE_PCT[1]:
        raise InputError(f"tolerance_pct: must lie in [{TOLERANCE_RANGE_PCT[0]:g}, {TOLERANCE_RANGE_PCT[1]:g}] %, "
                         f"got {case.tolerance_pct:g}")
    for k in ("size_body_mm", "size_feature_mm", "size_fillet_mm", "grading_mm",
              "approximate_span_mm", "exact_span_mm"):
        v = getattr(case, k)
        if v is not None:
            _finite_positive(k, v)
    check_spans(case)
    check_bearing(case)
    check_sensitivity(case)
    spec = case.mesh_spec()
    for k, size, least in (("size_body_mm", spec.size_body, 1e-3), ("size_feature_mm", spec.size_feature, 2e-4),
                           ("size_fillet_mm", spec.size_fillet, 2e-4)):
        if size * spec.factor < least * case.dims.b6:
            raise InputError(f"{k}: {size:g} mm x mesh_factor {spec.factor:g} is below {least:g} * b6 = "
                             f"{least * case.dims.b6:g} mm; a mesh this fine would need more elements than this tool allows")
    for k, size in (("size_body_mm", spec.size_body), ("size_feature_mm", spec.size_feature),
                    ("size_fillet_mm", spec.size_fillet)):
        if size * spec.factor > case.dims.b6:
            raise InputError(f"{k}: {size * spec.factor:g} mm is larger than the part ({case.dims.b6:g} mm)")
    if not case.name or case.name != case.name.strip() or any(c in case.name for c in "/\\") or \
            case.name in (".", "..") or \
            not case.name.isprintable() or len(case.name.encode("utf-8", "replace")) > 200:
        raise InputError(f"name: {case.name!r} cannot be used as a folder name")
    return case
