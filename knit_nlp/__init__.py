"""knit_nlp: mechanics of knitted fabrics as nonlinear programs.

Two published models: the weft-knit loop model of Wada et al. (``knit_nlp.weft``) and the
double-jacquard warp-knit mass-spring model of Zhang et al. (``knit_nlp.jacquard``).
"""
__version__ = "0.1.0"
