"""c't-Sim's light sensors as its Java3D cone-ray pick sees its lamps (`sim.world.kernels.light_pick`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.world import World, layout
from sim.world.files import load_world
from sim.world.kernels.light_pick import LAMP_MESH, pick_lamps
from sim.world.spec import WorldSpec

PARCOURS = """<?xml version="1.0" encoding="UTF-8"?>
<world><parcours>
<line>#######</line>
<line>#     #</line>
<line>#  *  #</line>
<line>#     #</line>
<line>#     #</line>
<line>#     #</line>
<line>#1    #</line>
<line>#######</line>
</parcours></world>
"""


def test_the_lamp_mesh_is_java3d_s_sphere_of_16_divisions():
    """Java3D's Sphere rounds c't-Sim's 15 divisions up to 16: per quarter round its axis and
    half, strips of 1, 3, 5 and 7 triangles from the pole: 128 triangles, every corner on the
    7 cm sphere (single precision), the poles on its axis."""
    assert LAMP_MESH.shape == (128, 3, 3)
    assert np.allclose(np.linalg.norm(LAMP_MESH, axis=2), 0.07, atol=1e-7)
    assert LAMP_MESH[0, 1].tolist() == [0.0, float(np.float32(0.07)), 0.0]  # the first strip's pole


def test_a_light_sensor_looking_at_a_lamp_reads_its_pole_not_its_nearest_surface(tmp_path):
    """A sensor 0.912 m south of a lamp, 32 mm east of it, 0.425 m below its centre, looking
    north: of each triangle the pick takes the first edge ahead, keyed by the distance along the
    ray to its closest approach, and the triangles round the south pole have the smallest key,
    so it reads the pole, 0.943723 m away (the real c't-Sim at this pose in testparcours2.xml,
    whose lamp stands at the same float place: 0.9437228876939844), not the nearest surface point
    (0.936674 m: the distance to the centre less 7 cm)."""
    path = tmp_path / "lamp.xml"
    path.write_text(PARCOURS)
    world = World(load_world(path, pillars="cylinder"))
    lamp = world.spec.lights[0]
    assert lamp.position == (float(np.float32(3.5) * np.float32(0.24)), float(np.float32(5.5) * np.float32(0.24)))  # c't-Sim's float place
    at = np.array((0.872, 0.408, 0.075))
    read = pick_lamps(at, np.array((0.0, 1.0, 0.0)), math.tan(math.pi / 2), world._lights, world._pick_tree)
    pole = math.dist(at, (lamp.position[0], lamp.position[1] - float(np.float32(0.07)), 0.5))
    assert read == pytest.approx(pole, abs=1e-12)
    assert round(read, 9) == round(0.9437228876939844, 9)
    assert math.dist(at, (*lamp.position, 0.5)) - 0.07 == pytest.approx(0.936674, abs=1e-6)


def test_a_lamp_whose_centre_lies_behind_the_sensor_is_not_seen():
    """Java3D's bounds test measures a box whose centre lies behind the ray's start from that
    start, where the cone's radius is 0: a lamp 1 mm behind the sensor's plane is not picked,
    though half of it lies in the 90° cone; 1 mm ahead, it is."""
    world = World(WorldSpec("w", (-1, -1, 1, 1)))
    lights = layout.LIGHTS.new(1)
    for ahead, seen in ((-0.001, False), (0.001, True)):
        lights["x"], lights["y"], lights["height"], lights["radius"] = 0.3, ahead, 0.5, 0.07
        read = pick_lamps(np.array((0.0, 0.0, 0.075)), np.array((0.0, 1.0, 0.0)), math.tan(math.pi / 2), lights, world._pick_tree)
        assert (read < math.inf) == seen
