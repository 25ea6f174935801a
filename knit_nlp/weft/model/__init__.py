"""The weft-knit loop model itself (Wada et al.): the basis and quadrature of eqs. 1 and 14-16
(``basis``, ``quadrature``), the unloaded loop (``natural``), the crossings of eqs. 2-5
(``crossings``), per-loop positions (``kinematics``), stored energy (``energy``, eqs. 6-12),
sampled centrelines (``centrelines``), a checked problem (``problem``), what a solve may change
(``params``) and how the loops are parametrised (``parametrisation``); ``cases`` holds the
shared load cases. Nothing here builds or solves an NLP."""
