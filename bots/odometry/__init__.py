"""Odometry: what a robot believes about its pose, from its own readings only.

The shipped estimators one file each with their compiled step (`encoder`, `firmware`, `mouse`,
`fused`, and a general chassis's in `chassis`) on the shared dead reckoning of `base` and the
shared error models of `propagation`; their parameters, state and the default estimates by name
declared in `layout`; the defaults of a run's robots (`defaults`) stepped in one compiled pass
(`batch`); a user's own estimator (`user`).
"""
