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
from geometry.table import Dimensions, InputError, lookup, validate

from pipeline.inputs.choices import MODELS, SOLVERS, SUPPORTS, WANTS
from pipeline.inputs.tomlfile import read_toml

DIMENSION_KEYS = tuple(f.name for f in fields(Dimensions))


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
    size_body_mm: float | None = None
    size_feature_mm: float | None = None
    size_fillet_mm: float | None = None
    grading_mm: float | None = None
    approximate_span_mm: float | None = None
    exact_span_mm: float | None = None
    want: str = "both"
    assumed: tuple[str, ...] = field(default_factory=tuple)

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
    "model": {"model": ("model", (str,)), "support": ("support", (str,)), "want": ("want", (str,))},
    "mesh": {"order": ("order", (int,)), "factor": ("mesh_factor", _NUM),
             "size_body_mm": ("size_body_mm", _NUM), "size_feature_mm": ("size_feature_mm", _NUM),
             "size_fillet_mm": ("size_fillet_mm", _NUM), "grading_mm": ("grading_mm", _NUM)},
    "solver": {"solver": ("solver", (str,)), "rtol": ("rtol", _NUM)},
    "analytic": {"approximate_span_mm": ("approximate_span_mm", _NUM),
                 "exact_span_mm": ("exact_span_mm", _NUM)},
}


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

    Overrides use Case field names, or 'dims.<name>' for a dimension.
    """
    values: dict[str, Any] = {}
    if case_file is not None:
        values.update(read_case_file(case_file))
        if size is not None and "size" in values and str(values["size"]) != str(size):
            raise InputError(f"size: --size {size} conflicts with size = \"{values['size']}\" in "
                             f"{case_file}; give one of them")
    values.update({k: v for k, v in (overrides or {}).items() if v is not None})
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
    name = values.pop("name", None) or row.size
    load = values.pop("load_N", row.load_N)
    assumed = tuple(k for k in ("dj", "rf", "seat_inner", "seat_outer") if k not in dim_over)
    case = Case(name=str(name), size=row.size, source=row.source, dims=dims, load_N=load,
                assumed=assumed, **values)
    return check(case)


def _finite_positive(name: str, v: Any, allow_zero: bool = False) -> None:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InputError(f"{name}: must be a number, got {v!r}")
    if not math.isfinite(v):
        raise InputError(f"{name}: must be finite, got {v!r}")
    if v < 0 or (v == 0 and not allow_zero):
        raise InputError(f"{name}: must be > 0, got {v:g}")


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
    """The formulas' spans must give them a positive lever arm (docs/design.md §4).

    Approximate method: the reaction's lever l/2 must exceed the bearing load's Dm/pi.
    Exact method: the curved bar needs the reaction outside the ring, l/2 > R = (b1 + di)/4.
    """
    from pipeline.post.formulas import paper_spans
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
    _finite_positive("rtol", case.rtol)
    if case.rtol >= 1e-3:
        raise InputError(f"rtol: solver tolerance must be below 1e-3, got {case.rtol:g}")
    _finite_positive("mesh_factor", case.mesh_factor)
    if not 0.05 <= case.mesh_factor <= 20:
        raise InputError(f"mesh_factor: must lie in [0.05, 20], got {case.mesh_factor:g}")
    for k in ("size_body_mm", "size_feature_mm", "size_fillet_mm", "grading_mm",
              "approximate_span_mm", "exact_span_mm"):
        v = getattr(case, k)
        if v is not None:
            _finite_positive(k, v)
    check_spans(case)
    spec = case.mesh_spec()
    for k, size, least in (("size_body_mm", spec.size_body, 1e-3), ("size_feature_mm", spec.size_feature, 2e-4),
                           ("size_fillet_mm", spec.size_fillet, 2e-4)):
        if size * spec.factor < least * case.dims.b6:
            raise InputError(f"{k}: {size:g} mm x mesh_factor {spec.factor:g} is below {least:g} * b6 = "
                             f"{least * case.dims.b6:g} mm; a mesh this fine would need more elements than this tool allows")
    if spec.size_body * spec.factor > case.dims.b6:
        raise InputError(f"size_body_mm: {spec.size_body * spec.factor:g} mm is larger than the part ({case.dims.b6:g} mm)")
    if not case.name or case.name != case.name.strip() or any(c in case.name for c in "/\\") or \
            case.name in (".", "..") or \
            not case.name.isprintable() or len(case.name.encode("utf-8", "replace")) > 200:
        raise InputError(f"name: {case.name!r} cannot be used as a folder name")
    return case


def check_error_bar_meshes(case: Case, levels: int, ratio: float) -> None:
    """Raise InputError unless the coarsest mesh of the error bar (mesh factor ×
    ratio^(levels − 1)) passes the case's checks: a run never solves a mesh it refuses."""
    coarsest = case.mesh_factor * ratio ** (levels - 1)
    try:
        check(replace(case, mesh_factor=coarsest))
    except InputError as exc:
        raise InputError(f"levels: the coarsest error-bar mesh (mesh factor {case.mesh_factor:g} x "
                         f"{ratio:g}^{levels - 1} = {coarsest:.3g}) is not allowed: {exc}; "
                         "use fewer levels or a smaller ratio") from None
