"""The finite-element model: mesh, loads and supports, elasticity, assembly, preconditioner, solve."""
