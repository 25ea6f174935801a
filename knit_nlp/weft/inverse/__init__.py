"""Inverse problems through the weft equilibrium (docs/inverse.md).

``spec`` reads the control keys of a problem file (actuated clamps, bounds, goals, openings);
``points`` evaluates material points of a solution symbolically; ``equilibrium`` holds the
built forward NLP with its KKT sensitivities and second-order check; ``control``, ``fit`` and
``overlay`` are the three commands; ``plot`` draws their pictures; ``run`` holds the CLI entry
points.
"""
