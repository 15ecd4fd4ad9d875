"""The world's compiled per-step kernels, one pass over all robots each, split by job: a robot's
motion over a step (`motion`), what stops it (`contacts`), the grids that find what is near
(`grids`), the floor raster and its one hole test (`floor`), plane geometry (`geometry`), the
sensors (`sensing`) and their random errors (`noise`). They read the world's packed tables by the
columns of `sim.world.layout`.

A world step is a handful of scalar formulas per robot (motor, encoders, arc, mouse, floor and
light sensors). Written with numpy they cost a few microseconds of call overhead each, which
dominates for one robot; these numba kernels do the same maths from `sim.kinematics` in one call
per step for any number of robots (tests compare them with the reference functions).
"""
