"""Near-limit rows: solve with a mesh-quality figure, or refuse clearly.

Units mm, N, MPa. Each row is No. 05 with a few dimensions pushed towards a rule of
geometry.table.validate. A row either

- meshes and solves: then it reports the worst curved-element quality
  (Level.jacobian_ratio = min over tets of min det J / max det J; <= 0 is an inverted
  element and the pipeline refuses it; the builder keeps every curved tet at >= 0.3), and
  the solver must converge in fewer than MAX_ITERATIONS with a true residual <= 1e-6; or
- is refused with InputError (a rule of the table broken: exit 2 in the CLI), whose
  message is one line that starts with the fields the rule constrains.

Every row marked "solve" solves today, the thinnest included (a 1 mm ligament, a
0.2 mm fillet, a fillet 0.1 mm short of the height limit): a regression to a refusal or a
failure shows here. Run with ``pytest -s`` for the table of iteration counts.
Coarse meshes (factor 2.5): a few seconds in all.
"""
from __future__ import annotations

import math
import time

import pytest

from geometry.part import GeometryError
from pipeline.inputs.case import resolve
from pipeline.errors import InputError, NumericalError
from pipeline.analysis.level import LevelTask, solve_level

FACTOR = 2.5
# A cap far above the default solver's (CG + p-multigrid) ~25-40 on sound meshes; 1000 is the solver's own.
MAX_ITERATIONS = 200

# name: (dimension overrides in mm, expected outcome, what it tests). No. 05: b1 45, b2 12.5,
# b6 70, d14 31, d2 21, h3 25, dj 20, rf 1.5, seat 25..37 (limits in geometry/table.py).
ROWS = {
    "thin ligament 2 mm": ({"d2": 41, "seat_inner": 42, "d14": 43, "seat_outer": 44}, "solve",
                           "(b1 - d2)/2 = 2 mm beside the bore; seat squeezed between bore and edge"),
    "thin ligament 1 mm": ({"d2": 43, "seat_inner": 43.5, "d14": 44, "seat_outer": 44.5}, "solve",
                           "(b1 - d2)/2 = 1 mm, seat band 1 mm wide"),
    "tiny fillet": ({"rf": 0.2}, "solve", "rf = 0.2 mm (0.008 h3): 0.05 mm elements on the fillet"),
    "large fillet": ({"rf": 2.4}, "solve", "dj/2 + rf = 12.4 mm, 0.1 mm short of h3/2"),
    "long journals": ({"b2": 40, "b6": 125}, "solve", "b2 = 40 mm (b2/dj = 2), b6 = b1 + 2 b2"),
    "short journals": ({"b2": 4, "b6": 53}, "solve", "b2 = 4 mm: 2.5 mm bearing length"),
    "tall body": ({"h3": 80}, "solve", "h3/b1 = 1.8 (default 0.56)"),
    "flat body": ({"h3": 8, "dj": 6, "rf": 0.5}, "solve", "h3/b1 = 0.18, dj 6 mm to fit the height"),
    # Just past a limit: refused before any meshing, naming the field.
    "fillet at the height limit": ({"rf": 2.5}, "refuse:dj, rf", "dj/2 + rf = h3/2: fillet runs out on the faces"),
    "bore as wide as the body": ({"d2": 45, "seat_inner": 45.5, "d14": 46, "seat_outer": 46.5},
                                 "refuse:d2", "no ligament"),
    "fillet longer than journal": ({"b2": 1.4, "b6": 47.8}, "refuse:rf", "rf = 1.5 > b2"),
}

TABLE: dict[str, dict] = {}


@pytest.fixture(scope="module", autouse=True)
def print_table():
    yield
    if not TABLE:
        return
    head = (f"{'row':28s} {'outcome':9s} {'DOFs':>6s} {'det J ratio':>11s} {'its':>4s} "
            f"{'residual':>8s} {'peak MPa':>9s} {'crit MPa':>9s} {'time s':>6s}")
    rtol = resolve("05").rtol
    lines = ["", f"geometry range, mesh factor {FACTOR}, CG + GAMG, rtol {rtol:g} "
             f"(worst curved-tet det J ratio):", head, "-" * len(head)]
    for name, r in TABLE.items():
        if "dofs" in r:
            lines.append(f"{name:28s} {r['outcome']:9s} {r['dofs']:6d} {r['jac']:11.3f} {r['its']:4d} "
                         f"{r['res']:8.1e} {r['peak']:9.1f} {r['crit']:9.1f} {r['time']:6.1f}")
        else:
            lines.append(f"{name:28s} {r['outcome']:9s} {r['message'][:110]}")
    print("\n".join(lines))


def _clear_message(exc: Exception) -> str:
    msg = str(exc)
    assert msg and "\n" not in msg.strip(), f"{type(exc).__name__} message is not one line: {msg!r}"
    return msg


@pytest.mark.slow
@pytest.mark.parametrize("name", list(ROWS))
def test_near_limit_row(name):
    dims, expect, _ = ROWS[name]
    overrides = {"mesh_factor": FACTOR, **{f"dims.{k}": v for k, v in dims.items()}}
    t0 = time.perf_counter()
    if expect.startswith("refuse:"):
        field = expect.split(":", 1)[1]
        with pytest.raises(InputError) as info:
            resolve("05", overrides=overrides)
        msg = _clear_message(info.value)
        assert msg.startswith(f"{field}:"), f"message should name {field!r}: {msg}"
        TABLE[name] = {"outcome": "refused", "message": f"InputError: {msg}"}
        return
    case = resolve("05", overrides=overrides)
    try:
        lv = solve_level(case, LevelTask(FACTOR))
    except (NumericalError, GeometryError) as exc:
        msg = _clear_message(exc)
        TABLE[name] = {"outcome": "failed", "message": f"{type(exc).__name__}: {msg}"}
        pytest.fail(f"{name}: expected to solve, got {type(exc).__name__}: {msg}")
    dt = time.perf_counter() - t0
    TABLE[name] = {"outcome": "solved", "dofs": lv.dofs, "jac": lv.jacobian_ratio, "its": lv.iterations,
                   "res": lv.residual_rel, "peak": lv.peak.value_MPa, "crit": lv.critical.value_MPa,
                   "time": dt}
    assert lv.jacobian_ratio > 0          # solve_level refuses inverted meshes; belt and braces
    # Second-order geometry on a part with a bore and round journals has curved tets, whose
    # det J varies inside the element: a ratio of exactly 1 means every tet is straight,
    # i.e. the mesh silently fell back to first order (gmsh's high-order optimiser can do
    # that; the mesher refuses a mesh without curved tets).
    assert lv.jacobian_ratio < 1 - 1e-9, f"{name}: no curved element, the mesh is first order"
    assert lv.iterations < MAX_ITERATIONS, f"{name}: {lv.iterations} CG iterations"
    assert lv.residual_rel <= 1e-6
    assert lv.equilibrium_error_N <= 1e-6 * case.load_N
    for pk in (lv.peak, lv.critical):
        assert math.isfinite(pk.value_MPa) and pk.value_MPa > 0
    # The critical peak lies on an edge where a face (z = 0 or h3) meets a stress raiser:
    # the bore (r = d2/2, the curved bar's inner fibre) or, on a tall body whose bending
    # stress is low, the seat's inner edge (r = seat_inner/2, where the seat pressure
    # starts). The region it is read from, the slab |x| <= d2/2, puts it on neither.
    x, y, z = lv.critical.location_mm
    d = case.dims
    r = math.hypot(x, y)
    assert min(abs(r - d.d2 / 2), abs(r - d.seat_inner / 2)) < 1e-3 * d.d2, \
        f"{name}: critical peak on neither the bore nor the seat's edge at {lv.critical.location_mm}"
    assert min(abs(z), abs(z - d.h3)) < 1e-6 * d.h3, f"{name}: critical peak off the faces at {lv.critical.location_mm}"
