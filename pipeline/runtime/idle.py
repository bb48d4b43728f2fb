"""Waiting for the other MPI ranks without taking a core from the work they wait for."""
from __future__ import annotations

import time


def wait_for_ranks(comm) -> None:
    """Wait for every rank of ``comm``, sleeping instead of spinning.

    Why: a rank waiting in a blocking MPI call spins at 100 % of a core (Open MPI's default),
    the core that the picture process and the other ranks' solves need: rank 1 waiting in
    the output folder's barrier while rank 0 waited for the picture left the picture and
    the plots one core between them.
    """
    request = comm.Ibarrier()
    while not request.Test():
        time.sleep(0.002)
