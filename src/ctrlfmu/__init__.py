"""Discrete control law (Eq. 11), python-control designs, and the controller FMU slave."""
