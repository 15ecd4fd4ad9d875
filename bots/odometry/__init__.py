"""Odometry: what a robot believes about its pose, from its own readings only.

The shipped estimators one file each (`encoder`, `firmware`, `mouse`, `fused`, and a general
chassis's in `chassis`) on the shared dead reckoning of `base`; their compiled steps in `steps`
(one file: numba caches a kernel by its own file's stamp); the defaults of a run's robots
(`defaults`) stepped in one compiled pass (`batch`); a user's own estimator (`user`).
"""
