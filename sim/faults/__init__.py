"""Fault injection: the test conductor's faults, on the simulator's side only.

``records`` the typed, validated fault records (plain data, what the ground's conductor
knows of them); ``condition`` the faulted state of the simulated hardware that the rover's
sensors and the scorer read (``sim.loop.rover_sim.RoverSim.condition``); ``plan`` a
rover's schedule of faults and their effects, applied when the simulator's clock reaches
them (docs/DESIGN.md, "Faults and training"). The flight software never sees any of it:
it learns of a fault only through what its sensors then measure.
"""
