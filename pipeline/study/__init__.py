"""Design studies: the plan of variants, running them over MPI ranks, their table, the size summary."""
