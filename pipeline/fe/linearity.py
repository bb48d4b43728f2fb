"""The scaling laws of this model, in one place: linear elasticity with traction loads only,
every load proportional to the hook load Q (N) and the stiffness to Young's modulus E (MPa).
So a solution at Q0, E0 gives every other load and modulus by a factor, exactly: the
stresses (MPa), forces and reactions (N) by Q/Q0, whatever E; the displacements (mm) by
(Q/Q0)·(E0/E). A load list, the run cache and the screening of a study all scale by these."""
from __future__ import annotations


def stress_factor(load_N: float, from_load_N: float) -> float:
    """The factor that takes a stress (MPa) or force (N) at hook load ``from_load_N`` to
    ``load_N`` (N): Q/Q0."""
    return load_N / from_load_N


def displacement_factor(load_N: float, E_MPa: float, from_load_N: float, from_E_MPa: float) -> float:
    """The factor that takes a displacement (mm) at ``from_load_N`` (N) and ``from_E_MPa``
    (MPa) to ``load_N`` and ``E_MPa``: (Q/Q0)·(E0/E)."""
    return (load_N / from_load_N) * (from_E_MPa / E_MPa)
