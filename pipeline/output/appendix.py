"""The report's appendix: the method written into the report itself, so that a reviewer
who has only the report can check it (mm, N, MPa): the load model; how this run read
its peaks and made their error bars; the two hand formulas with this run's terms; the
sensitivity method with why each range; the finite-element solution's own figures; the
references. The report's first pages give the answer and point here for the method.

The error bar's texts have one home, pipeline/post/errorbar.py (TREND_TEXT, STATUS_TEXT);
the appendix quotes them rather than writing them again, and the status words are the
analysis's (pipeline.analysis.words).
"""
from __future__ import annotations

from pipeline.analysis.words import PEAK_STATUSES, range_text
from pipeline.output.texts import error_bar_text, location, num
from pipeline.post.errorbar import STATUS_TEXT, TREND_TEXT

# How the report's other sections name the parts of the appendix they rest on.
LOADS = "Appendix A.1"
ERROR_BAR = "Appendix A.2"
FORMULAS = "Appendix A.3"
SENSITIVITY = "Appendix A.4"
SOLUTION = "Appendix A.5"


def _load_model(case: dict) -> list[str]:
    """A.1: the loads, supports, symmetry and material of this run (mm, N, MPa)."""
    model, support = case["model"], case["support"]
    L = ["### A.1 Load model, supports, symmetry, material\n",
         f"- **Load**: the thrust bearing presses on the top face: a uniform pressure on the seat annulus "
         f"(diameters seat_inner to seat_outer), total Q = {case['load_N']:g} N, downwards (−z)."]
    if support == "bearing":
        shape = case.get("bearing_shape", "cosine")
        p = ("p(θ) = p0·cos θ on the lower half of the bearing surface (θ about the journal axis from "
             "straight down, |θ| ≤ 90°), p0 = Q/(π·rj·L), rj = dj/2" if shape == "cosine" else
             "a uniform normal pressure p0 on the lower half of the bearing surface, p0 = (Q/2)/(dj·L), "
             "the same vertical load on every mm² of the projected area")
        length, centre = case.get("bearing_length_mm"), case.get("bearing_centre_mm")
        band = ("over the whole journal beyond the shoulder fillet, x = b1/2 + rf to the tip b6/2"
                if length is None and centre is None else
                f"over a band of the journal ({'length ' + f'{length:g} mm' if length is not None else 'the longest'}"
                f"{', centred ' + f'{centre:g} mm' if centre is not None else ''} from the centre plane x = 0)")
        L.append(f"- **Supports** (`bearing`): the side plates carry each journal from below with {p}, "
                 f"{band}, Q/2 upwards per journal. Each pressure is scaled by its own integral over the "
                 "mesh's facets, so the loads balance to round-off; rigid-body motion is removed by the "
                 "symmetry planes and point constraints whose reactions must come out zero (checked: "
                 "below 1e-6·Q).")
    else:
        L.append("- **Supports** (`rigid`): u_z = 0 on the lower half of each journal's bearing surface. The "
                 "edges of that patch are stress singularities: a peak there has no finite value.")
    L.append("- **Symmetry**: part, load and supports are symmetric about x = 0 and y = 0. "
             + ("The model is the quarter x ≥ 0, y ≥ 0 carrying Q/4, with u_x = 0 on x = 0 and u_y = 0 on "
                "y = 0; fields.vtu and the pictures show it mirrored to the whole part." if model == "quarter" else
                "The model is the whole part (statically determinate point constraints)."))
    L.append(f"- **Material**: linear elastic, isotropic, E = {case['E_MPa']:g} MPa, ν = {case['nu']:g}; "
             "small displacements. With tractions only, the stresses do not depend on E, and every stress "
             "scales with Q.")
    L.append(f"- **Elements**: curved tetrahedra, displacement of order P{case['order']}, meshed by gmsh "
             "(OpenCASCADE geometry) and solved by DOLFINx, 3-D linear elasticity.\n")
    return L


def _error_bar(res: dict) -> list[str]:
    """A.2: how a peak is read and how its error bar is made (errorbar.py's texts), each of
    this run's peaks read that way, and what each peak status means."""
    fe = res["fe"]
    L = ["### A.2 Peaks and their error bar\n",
         "Von Mises is read two ways at each node: the largest of the element-node values of von Mises "
         "interpolated into a discontinuous space (*unaveraged*), and the von Mises of the stress "
         "averaged over the elements meeting at the node (*averaged*). At the shoulder fillet, a "
         "steep surface maximum resolved by a few elements, the unaveraged value lies above an "
         "independent reference and the averaged one below it (measured on 30 of 33 meshes), so the "
         "reported value at a fillet node is the midpoint of its two readings; everywhere else it is the "
         "unaveraged value (at the bore edge both lie within 0.2 % of the reference). A peak is the node "
         "of the largest reported value; its readings:\n"]
    for key, label in (("peak", "Global peak"), ("critical", "Critical peak")):
        b = fe[key]
        rule = "the midpoint of the two" if "midpoint" in b.get("definition", "") else "the unaveraged reading"
        L.append(f"- **{label}** ({b['feature']}): unaveraged {num(b['unaveraged_MPa'])} MPa, averaged "
                 f"{num(b['averaged_MPa'])} MPa, reported {rule}: **{num(b['value_MPa'])}** MPa, {error_bar_text(b)}.")
    L += ["", TREND_TEXT + " " + f"Trends: {STATUS_TEXT}\n",
          "Each peak's status, as the report, the terminal, the plots and results.json say it: "
          + "; ".join(f"*{word}*: {what}" for word, what in PEAK_STATUSES.items()) + ".\n"]
    return L


def _formulas(res: dict) -> list[str]:
    """A.3: the paper's two hand formulas in general form and worked for this run, with the
    published values where the size's row has them."""
    an = res["analytic"]
    pub = an.get("published")
    at, et, cs = an["approximate_terms"], an["exact_terms"], an["consistent_span"]
    L = ["### A.3 The two hand formulas (Imrak et al. 2007)\n",
         "Both describe the section through the bore, x = 0: the two ligaments of total width b − di "
         "(b = b1) and height h. Both are *nominal* stresses: no stress concentration.\n",
         "**Approximate** (beam on two supports): each half of the bearing load acts at its centroid Dm/π "
         "from the axis (a half circle of diameter Dm), the reactions at l/2:\n",
         "    Me = Q/2 · (l/2 − Dm/π),    σ = 6·Me / ((b − di)·h²)\n",
         f"Here l = {num(an['approximate_span_mm'])} mm: lever {num(at['lever_mm'], 3)} mm, Me = "
         f"{num(at['Me_Nmm'], 0)} N·mm, σ = **{num(an['approximate_MPa'])} MPa**"
         + (f" (published {num(pub['approximate_MPa'])})." if pub else ".") + "\n",
         "**Exact** (Rudenko's curved bar: the ring around the bore):\n",
         "    R  = (b + di)/4\n"
         "    N1 = (1 + 2l/R)·Q / (4π)\n"
         "    M1 = (−0.12 + 0.034·l/R)·Q·R\n"
         "    N2 = N1 − Q/π\n"
         "    M2 = 2·N1·R − (l/(4R) + 1/π)·Q·R − M1\n"
         "    σ  = M2/W + N2/F,  F = h·(b − di)/2,  W = h·((b − di)/2)²/6\n",
         f"Here l = {num(an['exact_span_mm'])} mm, R = {num(et['R_mm'])} mm:\n"]
    terms = [("N1 (N)", "N1_N", 1), ("M1 (N·mm)", "M1_Nmm", 0), ("N2 (N)", "N2_N", 1), ("M2 (N·mm)", "M2_Nmm", 0),
             ("F (mm²)", "F_mm2", 1), ("W (mm³)", "W_mm3", 1)]
    L.append("| | " + " | ".join(name for name, _, _ in terms) + " | σ = M2/W + N2/F (MPa) |")
    L.append("|---|" + "---|" * (len(terms) + 1))
    L.append("| this run | " + " | ".join(num(et[key], 1) for _, key, _ in terms) + f" | **{num(an['exact_MPa'])}** |")
    if pub:
        L.append("| published | " + " | ".join(num(pub[key], nd) if key in pub else "" for _, key, nd in terms)
                 + f" | {num(pub['exact_MPa'])} |")
    L.append("")
    L.append("The paper's text writes R = (b − di)/4, but its worked example uses (b + di)/4, which is "
             "followed here. It takes the span l = b1 + b2 (journal centres) in the approximate method and l = b6 "
             f"in the exact one; with one span for both, the approximate formula at l = {num(an['exact_span_mm'], 1)} mm "
             f"gives {num(cs['approximate_at_exact_span_MPa'])} MPa and the exact one at "
             f"l = {num(an['approximate_span_mm'], 1)} mm {num(cs['exact_at_approximate_span_MPa'])} MPa."
             + (f" Published FE result: {num(pub['fe_MPa'])} MPa ({pub['source']})." if pub else "") + "\n")
    return L


def _sensitivity(res: dict) -> list[str]:
    """A.4: the sensitivity method, and why each of this run's ranges (with where a geometry
    rule clipped it or an end could not be analysed)."""
    L = ["### A.4 Sensitivity to the assumed inputs\n",
         "The paper does not give the journal diameter dj, the shoulder fillet radius rf or the seat "
         "annulus, and the bearing load's shape and place along the journal are choices of the model. "
         "Each such input the case did not set is varied alone over a stated range (defaults: dj ± 10 %, "
         "rf ± 20 %, each seat diameter ± 0.06·Dm, kept inside the geometry rules; a case may give its "
         "own ranges), the others kept. Each end of a dimension's range is analysed on one mesh coarser "
         "than the run's, refined at the places its dimensions name (no pilot solve); the nominal case on "
         "the same mesh is the baseline, so an end's value is the run's value × end / baseline and the "
         "coarser mesh's bias cancels. The nominal case on a second mesh measures the noise of one such "
         "mesh, stated beside the changes. Each end of a load-model choice is solved on one of the run's "
         "own meshes with its operator (a new right-hand side), with that mesh's own value as the baseline. "
         "The capacity is the hook load at which the first checked stress reaches the allowable; the "
         "verdict holds over the ranges or the report names the input and value where it flips.\n"]
    entries = res.get("sensitivity") or []
    if entries:
        L.append("Why each range:\n")
        for e in entries:
            why = e["reason"] + (f"; {e['note']}" if e.get("note") else "")
            bad = [f"{'low' if i == 0 else 'high'} end not analysed: {w}" for i, w in enumerate(e["invalid"]) if w]
            L.append(f"- **{e['input']}** {range_text(e['range'], e['unit'])}: {why}"
                     + ("; " + "; ".join(bad) if bad else "") + ".")
        L.append("")
    return L


def _solution(res: dict) -> list[str]:
    """A.5: the finite-element solution's own figures: size, solver, equilibrium, the worst
    element, where the meshes were refined, and the stages' times (s)."""
    fe, c = res["fe"], res["case"]
    ms = c["mesh_sizes_mm"]
    L = ["### A.5 The finite-element solution\n",
         f"Requested mesh: {fe['cells']} tetrahedra, {fe['dofs']} DOFs; {fe['iterations']} solver iterations "
         f"(`{c['solver']}`), true relative residual {fe['residual_rel']:.1e}; {fe['mpi_ranks']} MPI rank(s). "
         f"Worst element det J ratio {fe['mesh_min_jacobian_ratio']:.3f} (≤ 0 would be an inverted element"
         + ("; below 0.1 is poor" if fe['mesh_min_jacobian_ratio'] >= 0.1 else "; **below 0.1: poor, check the mesh**")
         + f"). Equilibrium: seat load {num(fe['seat_force_N'], 3)} N, support {num(fe['support_force_N'], 3)} N on "
         f"the model (share {fe['model_load_share']:g} of Q); imbalance {fe['equilibrium_error_N']:.2e} N; force "
         f"carried by the rigid-motion constraint {fe['constraint_reaction_N']:.2e} N (limit 1e-6·Q).\n",
         f"Mesh sizes (× factor {c['mesh_factor']:g}): body {num(ms['size_body'], 3)} mm, bore and seat edges "
         f"{num(ms['size_feature'], 3)} mm, fillets {num(ms['size_fillet'], 3)} mm, grading distance "
         f"{num(ms['grading'], 3)} mm." + _refined_text(fe, ms) + "\n"]
    scaled = [lv["mesh_factor"] for lv in fe["levels"] if lv.get("scaled_from")]
    if scaled:
        src = next(lv["scaled_from"] for lv in fe["levels"] if lv.get("scaled_from"))
        L.append(f"Not solved again: on the mesh(es) ×{', ×'.join(f'{f:g}' for f in scaled)} the displacement is an "
                 f"earlier run's solution of the same mesh and problem at Q = {num(src['load_N'], 1)} N, E = "
                 f"{num(src['E_MPa'], 0)} MPa, scaled by the load ratio and the inverse modulus ratio (exact in "
                 "linear elasticity; the solver figures above are that solve's); on an error-bar mesh the earlier "
                 "run's peaks and forces themselves are scaled, the mesh is not read again.\n")
    times = "; ".join(f"{k.replace('_', ' ')} {v:.1f}" for k, v in res["timings_s"].items())
    L.append(f"Timings (s): {times}. The stages before the pilot are the requested mesh's; the error-bar meshes "
             "and the picture run beside it, so the stages add up to more than the total (the wall time).\n")
    return L


def _refined_text(fe: dict, ms: dict) -> str:
    """Where and how finely the meshes were refined, in one sentence (mm); results.json's
    fe.refined_at_mm lists the places."""
    spots = fe.get("refined_at_mm") or []
    if not spots or "size_hotspot" not in ms:
        return ""
    if fe.get("refined_places_from") == "known":
        where = (f"{len(spots)} places known from the dimensions, the bore edges in x = 0 (no pilot solve: only "
                 "the critical peak is asked for, and it fell inside their refinement)")
    else:
        between = fe.get("refined_bridging_places") or 0
        where = (f"{len(spots) - between} places where a pilot solve (mesh × {fe['pilot_mesh_factor']:.3g}) found "
                 f"von Mises within {100 * (1 - fe['pilot_fraction']):.0f} % of the global or critical peak"
                 + (f" and {between} added between neighbouring ones on the fillet's crest" if between else ""))
    sizes = f"{num(ms['size_hotspot'], 3)} mm within {num(ms['hotspot_radius'], 3)} mm"
    if "size_edge_hotspot" in ms:  # an older results.json has one size, or one radius
        edge_radius = ms.get("edge_hotspot_radius", ms["hotspot_radius"])
        sizes += (f" on the journal root and {num(ms['size_edge_hotspot'], 3)} mm within "
                  f"{num(edge_radius, 3)} mm elsewhere")
    first = ", ".join(location(p) for p in spots[:2])
    return (f" Refined to {sizes} (× factor) at {where}, e.g. {first} (every place in results.json's "
            "fe.refined_at_mm; their mirror images too).")


REFERENCES = ["### References\n",
              "- Imrak, C. E., Erdil, A., Fetvacı, C. (2007), *Sigma*: the crosshead of DIN 15412 hooks, "
              "its two hand formulas and their worked example (No. 05, 10 kN).",
              "- Roache, P. J. (1998): *Verification and Validation in Computational Science and "
              "Engineering*, the grid convergence index.",
              "- Celik, I. B. et al. (2008): procedure for estimation and reporting of uncertainty due "
              "to discretization in CFD applications, *J. Fluids Eng.* 130.",
              "- Eça, L., Hoekstra, M. (2014): a procedure for the estimation of the numerical "
              "uncertainty of CFD calculations based on grid refinement studies, *J. Comput. Phys.* 262.\n"]


def appendix_lines(res: dict) -> list[str]:
    """The appendix of report.md for the run ``res`` (results.json): A.1 to A.5 and the references."""
    return ["## Appendix: the method\n",
            "What the numbers above rest on, so that this report can be checked on its own.\n",
            *_load_model(res["case"]), *_error_bar(res), *_formulas(res), *_sensitivity(res), *_solution(res),
            *REFERENCES]
