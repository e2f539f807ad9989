"""The analyses: drivers over any problem of the protocol (jointfem.hbm.problem).

frf: the nonlinear forced response by arclength continuation in omega.  compare: every ROM
against a reference, speed against accuracy.  (Next: nonlinear modes, stability, preload.)
"""
