"""The report's appendix: the method's essentials written into the report itself (load
model, how the peaks are read and their error bar, the two hand formulas, the sensitivity
method, the references), so that a reviewer who has only the report can check it. Units mm,
N, MPa.

The error bar's texts have one home, pipeline/post/errorbar.py (TREND_TEXT, STATUS_TEXT);
the appendix quotes them rather than writing them again.
"""
from __future__ import annotations

from pipeline.post.errorbar import STATUS_TEXT, TREND_TEXT

# How the report's other sections name the parts of the appendix they rest on.
LOADS = "Appendix A.1"
ERROR_BAR = "Appendix A.2"
FORMULAS = "Appendix A.3"


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


def _error_bar() -> list[str]:
    """A.2: how a peak is read and how its error bar is made (errorbar.py's texts)."""
    return ["### A.2 Peaks and their error bar\n",
            "Von Mises is read two ways at each node: the largest of the element-node values of von Mises "
            "interpolated into a discontinuous space (*unaveraged*), and the von Mises of the stress "
            "averaged over the elements meeting at the node (*averaged*). At the shoulder fillet, a "
            "steep surface maximum resolved by a few elements, the unaveraged value lies above an "
            "independent reference and the averaged one below it (measured on 30 of 33 meshes), so the "
            "reported value at a fillet node is the midpoint of its two readings; everywhere else it is the "
            "unaveraged value (at the bore edge both lie within 0.2 % of the reference). A peak is the node "
            "of the largest reported value. Each peak's definition and error-bar rule "
            "for this run are under *How the peaks are read*.\n",
            TREND_TEXT + "\n",
            f"Statuses: {STATUS_TEXT}\n"]


def _formulas() -> list[str]:
    """A.3: the paper's two hand formulas in general form (their terms for this run: section
    *Hand formulas*)."""
    return ["### A.3 The two hand formulas (Imrak et al. 2007)\n",
            "Both describe the section through the bore, x = 0: the two ligaments of total width b − di "
            "(b = b1) and height h.\n",
            "**Approximate** (beam on two supports): each half of the bearing load acts at its centroid Dm/π "
            "from the axis (a half circle of diameter Dm), the reactions at l/2:\n",
            "    Me = Q/2 · (l/2 − Dm/π),    σ = 6·Me / ((b − di)·h²)\n",
            "**Exact** (Rudenko's curved bar: the ring around the bore):\n",
            "    R  = (b + di)/4\n"
            "    N1 = (1 + 2l/R)·Q / (4π)\n"
            "    M1 = (−0.12 + 0.034·l/R)·Q·R\n"
            "    N2 = N1 − Q/π\n"
            "    M2 = 2·N1·R − (l/(4R) + 1/π)·Q·R − M1\n"
            "    σ  = M2/W + N2/F,  F = h·(b − di)/2,  W = h·((b − di)/2)²/6\n",
            "The paper's text writes R = (b − di)/4, but its worked example uses (b + di)/4, which is "
            "followed here. The paper takes the span l = b1 + b2 (journal centres) in the approximate method "
            "and l = b6 in the exact one; both are inputs, and each formula at the other's span is given "
            "beside it. Both are *nominal* stresses: no stress concentration.\n"]


def _sensitivity() -> list[str]:
    """A.4: the sensitivity method in one paragraph."""
    return ["### A.4 Sensitivity to the assumed inputs\n",
            "The paper does not give the journal diameter dj, the shoulder fillet radius rf or the seat "
            "annulus, and the bearing load's shape and place along the journal are choices of the model. "
            "Each such input the case did not set is varied alone over a stated range (defaults: dj ± 10 %, "
            "rf ± 20 %, each seat diameter ± 0.06·Dm, kept inside the geometry rules; a case may give its "
            "own ranges), the others kept. Each end of a range is analysed on one mesh coarser than the "
            "run's, with its own refinement; the nominal case on the same mesh is the baseline, so an end's "
            "value is the run's value × end / baseline and the coarser mesh's bias cancels. The nominal case "
            "on a second mesh measures the noise of one such mesh, stated beside the changes; the verdict "
            "holds over the ranges or the report names the input and value where it flips.\n"]


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
    """The appendix of report.md for the run ``res`` (results.json): A.1 to A.4 and the references."""
    return ["## Appendix: the method\n",
            "What the numbers above rest on, so that this report can be checked on its own.\n",
            *_load_model(res["case"]), *_error_bar(), *_formulas(), *_sensitivity(), *REFERENCES]
