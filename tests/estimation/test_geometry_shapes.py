"""The flight copy of the rover's shape (estimation.geometry) is the simulated rover's
(sim.rover.geometry): the same boxes, cylinders and wheels, number for number."""

from __future__ import annotations

from dataclasses import fields

from estimation.geometry import FLIGHT_GEOMETRY, ROVER_BOXES_B, ROVER_CYLINDERS_B
from sim.rover.geometry import MER_GEOMETRY, ROVER_BOXES, ROVER_CYLINDERS


def test_the_flight_shape_table_is_the_simulated_rovers() -> None:
    assert [(b.name, b.centre_b, b.size_m) for b in ROVER_BOXES] == list(ROVER_BOXES_B)
    assert [(c.name, c.centre_b, c.radius_m, c.length_m) for c in ROVER_CYLINDERS] == list(
        ROVER_CYLINDERS_B
    )


def test_the_flight_wheels_are_the_simulated_rovers() -> None:
    for f in fields(FLIGHT_GEOMETRY):
        assert getattr(FLIGHT_GEOMETRY, f.name) == getattr(MER_GEOMETRY, f.name), f.name
