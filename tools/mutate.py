"""Targeted mutation testing of the modules that decide the reported numbers (make mutate).

Each mutant is one small change of an operator or a constant in one module (the list
below: loads, elasticity, peaks and their reading rules, the error bar, sections, the hand
formulas, the sensitivity ranges, the field file's derived arrays, the cache's checks). It
is applied to a scratch copy of the tree (never to the checkout), and the fast tests of the
folders that test that module run against it (``pytest -x -m "not slow"``, with a time
limit). A mutant is *killed* when they fail, *survived* when they pass. A survivor is
either a gap in the tests or an equivalent mutant (a change no test can see because the
numbers do not change); the equivalent ones are listed here with the reason
(``equivalent=``) and reported as such. docs/testing.md gives the score and the list.

    python tools/mutate.py                 # every mutant (about 6 minutes on 2 cores)
    python tools/mutate.py --only B2 L1    # some of them
    python tools/mutate.py --list          # what each one changes

Exit status 0 when every mutant is killed or listed as equivalent, 1 otherwise.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TIMEOUT_S = 600  # per mutant: a mutant that hangs the tests counts as killed (it would hang a run)

# The fast tests that judge each module's mutants.
FE = ["tests/verification/test_verification.py", "tests/post/test_peaks.py", "tests/fe"]
LOADS = ["tests/fe/test_traction_pinned.py", "tests/fe/test_load_model.py"]
POST = ["tests/post", "tests/output/test_fields.py"]
ERRORBAR = ["tests/post/test_errorbar_pinned.py", "tests/post/test_convergence.py", "tests/post/test_peaks.py"]
SECTIONS = ["tests/post/test_sections.py", "tests/fe/test_load_model.py"]
FORMULAS = ["tests/post/test_analytic.py", "tests/fe/test_load_model.py", "tests/inputs"]
RANGES = ["tests/analysis"]
FIELDS = ["tests/output/test_fields.py"]
CACHE = ["tests/cache"]


@dataclass(frozen=True)
class Mutant:
    """``old`` (which must occur exactly once in ``path``) replaced by ``new``; ``tests`` the
    paths to run; ``equivalent`` why no test can kill it (empty: it must be killed)."""

    id: str
    path: str
    old: str
    new: str
    tests: tuple[str, ...]
    what: str
    equivalent: str = ""


def m(id_: str, path: str, old: str, new: str, tests: list[str], what: str, equivalent: str = "") -> Mutant:
    return Mutant(id_, path, old, new, tuple(tests), what, equivalent)


MUTANTS = [
    # pipeline/fe/loads.py: the seat and bearing pressures
    m("L1", "pipeline/fe/loads.py", "return -cos_t * n  # pointing up", "return -cos_t ** 1.2 * n  # pointing up", LOADS,
      "bearing pressure p0·cos θ → p0·cos^1.2 θ"),
    m("L2", "geometry/table.py", 'return 0.25 if model == "quarter"', 'return 0.255 if model == "quarter"', LOADS,
      "the quarter model's load share 0.25 → 0.255"),
    m("L3", "pipeline/fe/loads.py", "p_seat = fem.Constant(mesh, q_part / seat_area)",
      "p_seat = fem.Constant(mesh, 1.01 * q_part / seat_area)", LOADS, "seat pressure × 1.01"),
    m("L4", "pipeline/fe/loads.py", "seat_t = ufl.as_vector((0.0, 0.0, -p_seat))",
      "seat_t = ufl.as_vector((0.0, 0.0, p_seat))", LOADS, "seat pressure upwards"),
    m("L5", "pipeline/fe/loads.py", "        return -n\n", "        return n\n", LOADS, "uniform bearing pressure pulls"),
    m("L6", "pipeline/fe/loads.py", "r = ufl.sqrt(x[1] ** 2 + (x[2] - zc) ** 2)",
      "r = ufl.sqrt(x[1] ** 2 + 1.02 * (x[2] - zc) ** 2)", LOADS, "θ measured on an ellipse, not the journal's circle"),
    m("L7", "pipeline/fe/loads.py", "zc = fem.Constant(mesh, d.h3 / 2)", "zc = fem.Constant(mesh, d.h3 / 2.05)", LOADS,
      "the journal's axis 0.3 mm low"),
    m("L8", "pipeline/fe/loads.py", "p0 = fem.Constant(mesh, q_part / 2 / _integral(mesh, on_side[2], ds(bearing_id)))",
      "p0 = fem.Constant(mesh, q_part / 1.98 / _integral(mesh, on_side[2], ds(bearing_id)))", LOADS,
      "the full model's journals each carry 1 % more"),
    m("L9", "pipeline/fe/loads.py", "bt.value = -M0 / M1", "bt.value = M0 / M1", LOADS,
      "a band's tilt the wrong way (its resultant off its middle)"),
    m("L10", "pipeline/fe/loads.py", "p.value = share / (F0 + bt.value * F1)", "p.value = share / F0", LOADS,
      "a band's amplitude without its tilt's force"),
    m("L11", "pipeline/fe/loads.py", "ufl.And(ufl.ge(xs, a), ufl.le(xs, b))", "ufl.And(ufl.ge(xs, a), ufl.lt(xs, b))", LOADS,
      "a band's indicator open at its end b",
      equivalent="the indicator is sampled at quadrature points, and none of them lies exactly at x = b: "
                 "≤ and < give the same load vector"),
    m("L12", "pipeline/fe/loads.py", "if not (F0 > 0 and M1 > 0):", "if not (F0 > 0 or M1 > 0):", LOADS,
      "a band that holds no facet is not refused",
      equivalent="M1 = Σ f_z·(|x| − c)² over the load vector's nodes is positive whenever F0 is (a loaded "
                 "facet's nodes never all sit at x = c), so 'and' and 'or' refuse the same bands"),
    # pipeline/fe/elasticity.py: the material law and von Mises
    m("E1", "pipeline/fe/elasticity.py", "mu = self.E / (2 * (1 + self.nu))", "mu = self.E / (2 * (1 + 1.05 * self.nu))", FE,
      "shear modulus of ν × 1.05"),
    m("E2", "pipeline/fe/elasticity.py", "lam = self.E * self.nu / ((1 + self.nu) * (1 - 2 * self.nu))",
      "lam = self.E * self.nu / ((1 + self.nu) * (1 - 1.9 * self.nu))", FE, "λ with 1 − 1.9ν"),
    m("E3", "pipeline/fe/elasticity.py", "return 2.0 * mu * strain(u) + lam", "return 2.04 * mu * strain(u) + lam", FE,
      "stress with 2.04 μ ε"),
    m("E4", "pipeline/fe/elasticity.py", "return ufl.sqrt(1.5 * ufl.inner(dev, dev))",
      "return ufl.sqrt(1.5606 * ufl.inner(dev, dev))", FE, "von Mises × 1.02"),
    m("E5", "pipeline/fe/elasticity.py", 'exact = {"quadrature_degree": max(2 * (order - 1), 0)}',
      'exact = {"quadrature_degree": max(2 * (order - 1) - 1, 0)}', FE,
      "straight cells integrated one degree too low"),
    m("E6", "pipeline/fe/elasticity.py", "return bow > 1e-10 * size", "return bow > 1e-1 * size", FE,
      "curved cells taken for straight (low quadrature on them)"),
    # pipeline/post/peaks.py and the reading rules (pipeline/analysis/level.py, features.py)
    m("P1", "pipeline/post/peaks.py", 'return np.sqrt(1.5 * np.einsum("nij,nij->n", dev, dev))',
      'return np.sqrt(1.5606 * np.einsum("nij,nij->n", dev, dev))', POST, "averaged von Mises × 1.02"),
    m("P2", "pipeline/post/peaks.py", "return np.where(midpoint, 0.5 * (unaveraged + averaged), unaveraged)",
      "return np.where(midpoint, 0.55 * (unaveraged + averaged), unaveraged)", POST, "midpoint × 1.1"),
    m("P3", "pipeline/post/peaks.py", "return 0.5 * abs(self.unaveraged.value_MPa - self.averaged.value_MPa)",
      "return 0.6 * abs(self.unaveraged.value_MPa - self.averaged.value_MPa)", POST, "half-width × 1.2"),
    m("P4", "pipeline/post/peaks.py", "self.averaged.value_MPa, self.rule == MIDPOINT))",
      "self.averaged.value_MPa, self.rule != MIDPOINT))", POST, "the two rules swapped"),
    m("P5", "pipeline/post/peaks.py", "node[:, :9] / node[:, 9, None]", "node[:, :9] / (node[:, 9, None] + 1)", POST,
      "nodal average over one cell too many"),
    m("P6", "pipeline/post/peaks.py", "i = int(idx[np.argmax(values[idx])])", "i = int(idx[np.argmin(values[idx])])",
      POST, "the node of the smallest reported value taken"),
    m("P9", "pipeline/post/peaks.py", "np.maximum.at(best, cg, vm.x.array[dg])", "best[cg] = vm.x.array[dg]", POST,
      "a node's unaveraged reading from one of its cells, not the largest"),
    m("P8", "pipeline/post/peaks.py", 'W = fem.FunctionSpace(mesh, ("DG", max(order - 1, 0)))',
      'W = fem.FunctionSpace(mesh, ("DG", max(order - 2, 0)))', POST, "unaveraged von Mises one degree too low"),
    m("P7", "pipeline/post/peaks.py", "i = int(np.argmax(vals))", "i = int(np.argmin(vals))",
      POST + ["tests/verification/test_verification.py"], "a minimum for a peak (peak(): the verification problems')"),
    m("R1", "pipeline/analysis/level.py", "readings = node_readings(u, mat, fillet_region(case))",
      "readings = node_readings(u, mat, None)", POST, "the fillet read unaveraged"),
    m("R2", "pipeline/post/peaks.py", "else np.asarray(midpoint(xyz), dtype=bool)",
      "else ~np.asarray(midpoint(xyz), dtype=bool)", POST, "the midpoint taken off the fillet, not on it"),
    m("R3", "pipeline/analysis/level.py", "return node_peak(readings), node_peak(readings, critical_region(case))",
      "return node_peak(readings), node_peak(readings)", POST, "the critical peak taken over the whole part"),
    m("R4", "pipeline/post/features.py", "half = case.dims.d2 / 2 * (1 + 1e-9)", "half = case.dims.d2 * (1 + 1e-9)", POST,
      "the critical region twice as wide"),
    # pipeline/post/errorbar.py
    m("B1", "pipeline/post/errorbar.py", "FS = 1.25 ", "FS = 1.10 ", ERRORBAR, "Roache's Fs 1.25 → 1.10"),
    m("B2", "pipeline/post/errorbar.py", "band = fs * abs(f[0] - f0) + sigma + abs(f[0] - (f0 + C))",
      "band = fs * abs(f[0] - f0) + abs(f[0] - (f0 + C))", ERRORBAR, "least-squares band without its scatter term"),
    m("B3", "pipeline/post/errorbar.py", "band = fs * abs(mid[0] - f0) + sigma + abs(mid[0] - (f0 + (cu + cl) / 2.0))",
      "band = fs * abs(mid[0] - f0) + sigma", ERRORBAR, "two-reading band without its last term"),
    m("B4", "pipeline/post/errorbar.py", "fs = FS if p <= 2.0 * p_formal else 3.0", "fs = FS if p <= 1.5 * p_formal else 3.0",
      ERRORBAR, "Fs = 3 from 1.5·p_formal"),
    m("B5", "pipeline/post/errorbar.py", "p_used = min(p, p_formal)", "p_used = p", ERRORBAR,
      "three meshes' order not capped at the formal order"),
    m("B6", "pipeline/post/errorbar.py", "SETTLED_BAND = 1.5e-3", "SETTLED_BAND = 1.0e-3", ERRORBAR, "settled band 0.1 %"),
    m("B7", "pipeline/post/errorbar.py", "SETTLED = 1e-3 ", "SETTLED = 2e-3 ", ERRORBAR, "settled below 0.2 %"),
    m("B8", "pipeline/post/errorbar.py", "sigma = math.sqrt(res * n / (n - 2))", "sigma = math.sqrt(res * n / (n - 3))",
      ERRORBAR, "unconfirmed order's σ over n − 3"),
    m("B9", "pipeline/post/errorbar.py", "sigma = math.sqrt(res * n / (n - 3)) if n > 3 else 0.0",
      "sigma = math.sqrt(res * n / (n - 2)) if n > 3 else 0.0", ERRORBAR, "confirmed order's σ over n − 2"),
    m("B10", "pipeline/post/errorbar.py", "w = np.sqrt((1.0 / h) / np.sum(1.0 / h))", "w = np.sqrt(h / np.sum(h))",
      ERRORBAR, "least-squares weights ∝ h, not 1/h"),
    m("B11", "pipeline/post/errorbar.py", "k = 4 if confirmed else 3", "k = 3 if confirmed else 3", ERRORBAR,
      "two readings' σ with three parameters when four were fitted"),
    m("B12", "pipeline/post/errorbar.py", "band = max(est.band, half_width_MPa)", "band = min(est.band, half_width_MPa)",
      ERRORBAR, "a midpoint's band the smaller of trend and bracket"),
    m("B13", "pipeline/post/errorbar.py", 'return "pass" if hi <= allowable_MPa', 'return "pass" if hi < allowable_MPa',
      ERRORBAR, "at the allowable exactly: undecided instead of pass"),
    m("B14", "pipeline/post/errorbar.py", 'else "fail" if lo > allowable_MPa', 'else "fail" if lo >= allowable_MPa',
      ERRORBAR, "a band's bottom at the allowable: fail instead of undecided"),
    m("B15", "pipeline/post/errorbar.py", "P_SINGULAR = 0.5 ", "P_SINGULAR = 0.3 ", ERRORBAR,
      "orders from 0.3 trusted"),
    m("B16", "pipeline/post/errorbar.py", "ext = f1 + (f1 - f2) / (r21 ** p_used - 1)",
      "ext = f1 - (f1 - f2) / (r21 ** p_used - 1)", ERRORBAR, "Richardson the wrong way"),
    m("B17", "pipeline/post/errorbar.py", "sigma = math.sqrt(res / 2.0 * (2 * n) / (2 * n - k))",
      "sigma = math.sqrt(res * (2 * n) / (2 * n - k))", ERRORBAR, "two readings' σ twice its variance"),
    m("B18", "pipeline/post/errorbar.py", "return dofs ** (-1.0 / 3.0)", "return dofs ** (-1.0 / 2.0)", ERRORBAR,
      "a mesh's size as N^(-1/2), not N^(-1/3)"),
    # pipeline/post/sections.py
    m("S1", "pipeline/post/sections.py", "halves = 2.0 if share == 0.25 else 1.0", "halves = 1.0 if share == 0.25 else 1.0",
      SECTIONS, "the quarter's half section not doubled"),
    m("S2", "pipeline/post/sections.py", "m_loc = outward_sign * float(R.sum()), outward_sign * float(np.dot(R, c - centre_mm))",
      "m_loc = outward_sign * float(R.sum()), outward_sign * float(np.dot(R, c))", SECTIONS,
      "section moment about c = 0 instead of the section's centre"),
    m("S3", "pipeline/post/sections.py", "return integral(s) / L, 6.0 / L ** 2 * integral(s * (L / 2 - tt))",
      "return integral(s) / L, 6.1 / L ** 2 * integral(s * (L / 2 - tt))", SECTIONS, "linearised bending × 1.017"),
    m("S4", "pipeline/post/sections.py", "return M, 32.0 * M / (math.pi * d.dj ** 3)",
      "return M, 32.5 * M / (math.pi * d.dj ** 3)", SECTIONS, "journal nominal stress × 1.016"),
    m("S5", "pipeline/post/sections.py", '"membrane_MPa": N / (w * h), "bending_MPa": 6.0 * abs(M) / (w * h ** 2),',
      '"membrane_MPa": N / (w * h), "bending_MPa": 6.0 * abs(M) / (w * h ** 2.05),', SECTIONS,
      "section bending stress with h^2.05"),
    m("S6", "pipeline/post/sections.py", "lever = centre - d.b1 / 2", "lever = centre - d.b1 / 2 - d.rf", SECTIONS,
      "journal root's lever from the fillet's end"),
    # pipeline/post/formulas.py
    m("F1", "pipeline/post/formulas.py", "lever = span_mm / 2 - Dm / math.pi", "lever = span_mm / 2 - Dm / 3.0", FORMULAS,
      "approximate formula's lever with Dm/3"),
    m("F2", "pipeline/post/formulas.py", "M1 = (-0.12 + 0.034 * l / R) * Q_N * R", "M1 = (-0.12 + 0.035 * l / R) * Q_N * R",
      FORMULAS, "Rudenko's M1 coefficient 0.034 → 0.035"),
    m("F3", "pipeline/post/formulas.py", "W = h * width ** 2 / 6", "W = h * width ** 2 / 5", FORMULAS,
      "exact formula's section modulus /5"),
    m("F4", "pipeline/post/formulas.py", "N2 = N1 - Q_N / math.pi", "N2 = N1 - Q_N / 3.0", FORMULAS,
      "exact formula's N2 with Q/3"),
    m("F5", "pipeline/post/formulas.py", "R = (b + di) / 4", "R = (b + di) / 4.1", FORMULAS,
      "Rudenko's ring radius 2.5 % small"),
    # pipeline/analysis/ranges.py: the ranges' ends
    m("Se1", "pipeline/analysis/ranges.py",
      '    value = round(round(value / STEP_MM) * STEP_MM, 9)\n    if value <= limit:',
      '    value = round(value, 9)\n    if value <= limit:', RANGES, "a high end not rounded to 0.01 mm"),
    m("Se2", "pipeline/analysis/ranges.py", "capped = round(math.floor(limit / STEP_MM + 1e-9) * STEP_MM, 9)",
      "capped = round(math.ceil(limit / STEP_MM - 1e-9) * STEP_MM, 9)", RANGES, "a cap rounded outwards"),
    m("Se3", "pipeline/analysis/ranges.py", "raised = round(math.ceil(limit / STEP_MM - 1e-9) * STEP_MM, 9)",
      "raised = round(math.floor(limit / STEP_MM + 1e-9) * STEP_MM, 9)", RANGES, "a raised low end rounded outwards"),
    m("Se4", "pipeline/analysis/ranges.py", "DJ_SPREAD = 0.10 ", "DJ_SPREAD = 0.11 ", RANGES, "dj ± 11 %"),
    m("Se5", "pipeline/analysis/ranges.py", "RULE_MARGIN = 0.02\n", "RULE_MARGIN = 0.03\n", RANGES,
      "ranges 0.03·h3 inside the rules"),
    m("Se6", "pipeline/analysis/ranges.py", "nearest = min(cs.centre_standing[0], cs.centre_hanging[0])",
      "nearest = max(cs.centre_standing[0], cs.centre_hanging[0])", RANGES, "the load centre's range from the farthest"),
    m("Se7", "pipeline/analysis/ranges.py", "        return round(round(v / STEP_MM) * STEP_MM, 9)\n",
      "        return round(v, 9)\n", RANGES, "load-model range ends not rounded"),
    m("Se8", "pipeline/analysis/ranges.py", "SEAT_SPREAD = 0.06 ", "SEAT_SPREAD = 0.07 ", RANGES,
      "seats ± 0.07·Dm"),
    # pipeline/output/fields.py: the arrays derived for the field file
    m("Fi1", "pipeline/output/fields.py", "TENSOR_ORDER = [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2)]",
      "TENSOR_ORDER = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]", FIELDS, "yz and xz swapped"),
    m("Fi2", "pipeline/output/fields.py", "principal = np.linalg.eigvalsh(s)[:, ::-1]", "principal = np.linalg.eigvalsh(s)",
      FIELDS, "principal stresses smallest first"),
    m("Fi3", "pipeline/output/fields.py", "s = 0.5 * (s + s.transpose(0, 2, 1))", "s = 0.51 * (s + s.transpose(0, 2, 1))",
      FIELDS, "the written tensor × 1.02"),
    m("Fi4", "pipeline/output/fields.py", "VTK_TET10 = [0, 1, 2, 3, 9, 6, 8, 7, 5, 4]",
      "VTK_TET10 = [0, 1, 2, 3, 9, 8, 6, 7, 5, 4]", FIELDS, "two mid-edge nodes of the 10-node tet swapped"),
    m("Fi5", "pipeline/output/fields.py", "REPORTED: readings.as_function(readings.reported, \"reported\")}",
      "REPORTED: readings.as_function(readings.unaveraged, \"reported\")}", FIELDS,
      "the unaveraged reading written as the reported one"),
    # pipeline/cache: the checks of what is reused
    m("C1", "pipeline/cache/runs.py", "if hashlib.sha256(body).hexdigest() != digest:",
      "if hashlib.sha256(body[:n_header]).hexdigest() != digest:", CACHE, "the checksum read over the header only"),
    m("C2", "pipeline/cache/runs.py", "digest = hashlib.sha256(header + payload).hexdigest()",
      "digest = hashlib.sha256(header).hexdigest()", CACHE, "the checksum written over the header only"),
    m("C3", "pipeline/cache/runs.py", "if dtype not in DTYPES or not all(", "if not all(", CACHE,
      "an array of objects accepted"),
    m("C4", "pipeline/cache/runs.py", "if st.st_size > limit:", "if st.st_size > 2 * limit:", CACHE,
      "an entry twice the bound read"),
    m("C5", "pipeline/cache/levels.py", "if abs(m[\"seat_force_N\"] + share * load) > 1e-9 * share * load:",
      "if abs(m[\"seat_force_N\"] + share * load) > 1e-3 * share * load:", CACHE,
      "a stored seat force 0.1 % off accepted"),
    m("C6", "pipeline/cache/levels.py", "if max(m[\"equilibrium_error_N\"], m[\"constraint_reaction_N\"]) > 1e-6 * load:",
      "if m[\"equilibrium_error_N\"] > 1e-6 * load:", CACHE, "a constraint reaction out of balance accepted"),
    m("C7", "pipeline/fe/linearity.py", "return load_N / from_load_N", "return from_load_N / load_N", CACHE,
      "a stored result scaled by Q0/Q instead of Q/Q0"),
]


def scratch_copy(dest: Path) -> None:
    """The checkout's files (tracked, and new ones git does not ignore) copied into ``dest``."""
    names = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                           capture_output=True, check=True).stdout.decode().split("\0")
    for name in filter(None, names):
        src = ROOT / name
        if src.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / name)


def run_one(mu: Mutant, tree: Path) -> tuple[str, float]:
    """("killed" or "survived", seconds) of mutant ``mu`` applied in ``tree`` (restored after)."""
    path = tree / mu.path
    original = path.read_text(encoding="utf-8")
    if original.count(mu.old) != 1:
        raise SystemExit(f"{mu.id}: the text to mutate occurs {original.count(mu.old)} times in {mu.path}")
    path.write_text(original.replace(mu.old, mu.new), encoding="utf-8")
    t0 = time.perf_counter()
    try:
        env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
        p = subprocess.run([sys.executable, "-m", "pytest", "-x", "-q", "-m", "not slow", "-p", "no:cacheprovider",
                            *mu.tests], cwd=tree, capture_output=True, text=True, timeout=TIMEOUT_S, env=env)
        outcome = "survived" if p.returncode == 0 else "killed" if p.returncode == 1 else f"error {p.returncode}"
        if outcome.startswith("error"):
            sys.stderr.write(p.stdout[-2000:] + p.stderr[-2000:])
    except subprocess.TimeoutExpired:
        outcome = "killed"
    finally:
        path.write_text(original, encoding="utf-8")
    return outcome, time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="+", metavar="ID", help="run only these mutants")
    ap.add_argument("--list", action="store_true", help="list the mutants and exit")
    args = ap.parse_args(argv)
    chosen = [mu for mu in MUTANTS if not args.only or mu.id in args.only]
    if args.list:
        for mu in chosen:
            print(f"{mu.id:4} {mu.path}: {mu.what}" + (f"  [equivalent: {mu.equivalent}]" if mu.equivalent else ""))
        return 0
    results = []
    with tempfile.TemporaryDirectory(prefix="crosshead-mutate-") as tmp:
        tree = Path(tmp)
        scratch_copy(tree)
        for mu in chosen:
            outcome, seconds = run_one(mu, tree)
            note = f" (equivalent: {mu.equivalent})" if outcome == "survived" and mu.equivalent else ""
            print(f"{mu.id:4} {outcome:8} {seconds:6.1f} s  {mu.path}: {mu.what}{note}", flush=True)
            results.append((mu, outcome))
    killed = sum(o == "killed" for _, o in results)
    equivalent = [mu for mu, o in results if o == "survived" and mu.equivalent]
    gaps = [mu for mu, o in results if o != "killed" and not (o == "survived" and mu.equivalent)]
    print(f"\nscore: {killed}/{len(results)} killed; {len(equivalent)} equivalent; "
          f"{killed}/{len(results) - len(equivalent)} of the non-equivalent killed")
    for mu in gaps:
        print(f"not killed: {mu.id} {mu.path}: {mu.what}")
    return 0 if not gaps else 1


if __name__ == "__main__":
    sys.exit(main())
