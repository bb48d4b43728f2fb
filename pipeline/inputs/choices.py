"""The choices a case offers, listed once: validation, the command line and the stages
import them from here (no solver or mesher is loaded to check a case file)."""
from geometry.table import MODELS

SUPPORTS = ("bearing", "rigid")  # cosine bearing pressure, or u_z = 0 (singular edges)
SOLVERS = ("pmg", "gamg", "hypre", "mumps")  # CG + p-multigrid, CG + GAMG, CG + BoomerAMG, direct
ORDERS = (1, 2, 3)  # element order of the displacement
# What the run is asked for: both peaks, or only the critical (bore-ligament) or the
# global (fillet) one; a run skips the refinement the other would need.
WANTS = ("both", "critical", "global")
# The bearing pressure's shape over the lower half of each journal (docs/design.md §3):
# p0·cos θ, or a uniform normal pressure (uniform over the projected area dj × length).
BEARING_SHAPES = ("cosine", "uniform")
# Where --bearing-at puts the journal load: each hand formula's own span position (§4).
BEARING_AT = ("approximate", "exact")

__all__ = ["MODELS", "SUPPORTS", "SOLVERS", "ORDERS", "WANTS", "BEARING_SHAPES", "BEARING_AT"]
