"""Rehearsal of a sequence before uplink: the whole loop, flight software and simulated rover,
run many times on worlds sampled from what the ground knows (docs/DESIGN.md, "Rehearsal")."""
