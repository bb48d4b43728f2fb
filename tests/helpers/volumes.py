"""The part's volume (mm³) computed independently of the CAD builder, for geometry checks."""
import math

from scipy.integrate import quad


def volume_by_quadrature(d, model):
    """Body box − bore + journals, the fillet ring integrated numerically (independent of
    the Pappus formula the builder uses)."""
    rj, rf = d.dj / 2, d.rf
    body = d.b1 ** 2 * d.h3 - math.pi * d.d2 ** 2 / 4 * d.h3
    cyl = math.pi * rj ** 2 * d.b2
    ring, _ = quad(lambda s: math.pi * ((rj + rf - math.sqrt(rf ** 2 - (s - rf) ** 2)) ** 2 - rj ** 2), 0, rf)
    full = body + 2 * (cyl + ring)
    return full / 4 if model == "quarter" else full
