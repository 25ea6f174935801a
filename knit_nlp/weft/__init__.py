"""The weft-knit loop model of Wada et al. (spec/weft_loop_model.md).

Reading order follows the model: ``basis`` and ``quadrature`` (eqs. 1, 14-16) -> ``natural``
(the unloaded loop) -> ``crossings`` (eqs. 2-5) -> ``problem`` (a checked problem description)
-> ``energy`` (eqs. 6-12) -> ``nlp`` (eq. 13 with continuity 18-19 and clamps; the reduction of
eqs. 22-27 as a linear reparametrisation in ``reduction``) -> ``solve`` -> ``results`` -> ``plot``
and ``run`` (the CLI's entry points).
"""
