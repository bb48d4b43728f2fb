"""What a run is asked: the case (every input, defaults included), the choices it offers, lists of values."""
