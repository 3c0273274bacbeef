"""Fault injection on the server: the test conductor's faults on a rover (``service``: the
faults handed to a rover's session, listed, revealed; ``api``: the routes).

Faults are the simulator's truth (``sim.faults``): injected, listed and revealed by the
conductor role only, never shown to anyone below it until the conductor reveals them for the
debrief (then on the sol timeline, for everyone). See docs/DESIGN.md, "Faults and training".
"""
