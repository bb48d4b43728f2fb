"""crosshead: the finite-element analysis of a crane hook-block crosshead (DIN 15412), from the
case to the report (mm, N, MPa). Subpackages: docs/architecture.md."""

__version__ = "0.7.0.dev0"
