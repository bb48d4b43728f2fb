"""Running safely: the output folder, files written whole, stops, rank failures, memory, mpirun."""
