"""Solving a transcribed weft NLP with IPOPT: ``solve`` (direct, continuation, perturbed and
multilevel starts: the starts that solve live with the solver), ``starts`` (starting points
that need no solve) and ``adaptive`` (the adaptive-representatives strategy)."""
