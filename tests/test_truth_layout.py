"""What the ground may read of the simulator, pinned by imports (docs/DESIGN.md, "Two
records"): the rule that the ground never reads the simulator's truth, as a matter of
imports rather than of care.

Every module of ``server/`` may import from ``sim/`` only what a real ground system has too:
the Mars clock, the ephemeris and Mars frames, the landing sites and their terrain maps, the
rover's design geometry, the downlink's definition and the simulator's input errors
(``GROUND_KNOWLEDGE``). The truth records' definition (``sim.scoring.truth``) is imported by
the few modules that carry or serve the truth view (``TRUTH_CARRIERS``); the simulator
itself (a session, the world, the sensors, the scorer) only by the runtime that hosts it
(``SIMULATOR_HOSTS``). Anything else fails here, naming the import.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from tests.test_layout import ROOT, import_graph, modules_of

GROUND_KNOWLEDGE = frozenset({
    "sim.errors",  # the simulator's input errors, raised on bad arguments
    "sim.loop.downlink",  # what the rover sends: the ground's own record
    "sim.loop.images",  # the images the rover sends: their record (its estimate, no truth)
    "sim.world.marsclock",  # Mars time
    "sim.world.ephemeris",  # JPL's ephemeris, as a mission's navigation team has it
    "sim.world.light_time",  # Earth-Mars light time, from that ephemeris
    # the comm plan and the windows the ground predicts from published ephemerides
    "sim.comm.plan",
    "sim.comm.windows",
    "sim.world.mars_frames",  # the IAU's Mars frames
    "sim.world.sites",  # the landing sites' published coordinates and terrain maps
    "sim.world.terrain",  # a terrain map (the ground's orbital and stereo maps)
    # the orbital DEM and image the mapping team delivers: noisy, smoothed, posts 1 m
    "sim.world.orbital_map",
    "sim.rover.geometry",  # the rover's design drawings (for drawing it)
})  # fmt: skip
TRUTH = "sim.scoring.truth"
TRUTH_CARRIERS = frozenset({
    "server.access.truth_view",  # who may see the truth, and stripping it for the others
    "server.sinks",  # hands each frame's two records on
    "server.storage.store",  # stores and reads them
    "server.storage.columns",  # their columns, from the records' fields
    "server.storage.channels",  # a stored row back into its typed record
    "server.storage.migrate",  # splits frames stored as one record into the two
    "server.hub",  # the WebSocket: the truth only to those the truth view allows
    "server.alarms",  # alarms on truth channels (the truth view's)
    "server.channels",  # which channels are truth
    "server.api.telemetry",  # the truth record's schema
    "server.api.answers",  # the routes' answer models: a frame's truth fields, typed
    "server.api.telemetry_csv",  # its CSV columns
    "server.scene3d.scene",  # the 3D view's truth layer
})  # fmt: skip
SIMULATOR_HOSTS = frozenset({
    "server.runtime",  # hosts the rover sessions
    # host the link across light time (sim.comm.link: the rover's store, what is on its way)
    # and hand the live truth on; what the ground reads of them is their ground_view
    "server.comm.hosting",
    "server.comm.mission",
})  # fmt: skip
# The conductor's faults as data (what can fail, with which parameters): read only by the
# modules that serve the conductor's fault routes, never by the ground's.
FAULT_RECORDS = "sim.faults.records"
# A rehearsal runs a simulator on its OWN sampled worlds, built only from what the ground
# knows (the rover's last report, the ground's map, priors); it never touches the live session.
# So the rehearsal package reads its plain-data inputs and outcomes freely, and names the
# engine (``sim.rehearsal.run``) only as a string its Dask workers import, in one module.
REHEARSAL_DATA = frozenset({"sim.rehearsal.inputs", "sim.rehearsal.outcome"})
REHEARSAL_PACKAGE = "server.rehearsal"
REHEARSAL_ENGINE = "sim.rehearsal.run"
REHEARSAL_SUBMITTERS = frozenset({"server.rehearsal.cluster"})
FAULT_CONDUCTORS = frozenset({
    "server.faults.service",  # hands a fault to a rover's session, lists and reveals them
    "server.faults.api",  # the conductor's routes
})  # fmt: skip


def truth_violations(graph: Mapping[str, set[str]]) -> list[str]:
    """``importer -> imported`` for every import of ``sim`` a server module may not make."""
    wrong = []
    for importer, imported in sorted(graph.items()):
        if importer.split(".")[0] != "server":
            continue
        for target in sorted(t for t in imported if t.split(".")[0] == "sim"):
            allowed = (
                target in GROUND_KNOWLEDGE
                or (target == TRUTH and importer in TRUTH_CARRIERS)
                or (target == FAULT_RECORDS and importer in FAULT_CONDUCTORS)
                or (target in REHEARSAL_DATA and importer.startswith(REHEARSAL_PACKAGE + "."))
                or importer in SIMULATOR_HOSTS
            )
            if not allowed:
                wrong.append(f"{importer} -> {target}")
    return wrong


def test_the_ground_imports_only_ground_knowledge_of_the_simulator() -> None:
    wrong = truth_violations(import_graph(ROOT, ("server", "sim")))
    assert not wrong, f"server modules reading the simulator: {wrong}"


def engine_namers(root: Path) -> list[str]:
    """The server modules whose text names the rehearsal engine's module."""
    return sorted(
        name
        for name, path in modules_of(root, ("server",)).items()
        if REHEARSAL_ENGINE in path.read_text(encoding="utf-8")
    )


def test_only_the_submitting_module_names_the_rehearsal_engine() -> None:
    wrong = sorted(set(engine_namers(ROOT)) - REHEARSAL_SUBMITTERS)
    assert not wrong, f"server modules naming {REHEARSAL_ENGINE}: {wrong}"


def test_the_named_modules_exist() -> None:
    graph = import_graph(ROOT, ("server", "sim"))
    named = GROUND_KNOWLEDGE | TRUTH_CARRIERS | SIMULATOR_HOSTS | FAULT_CONDUCTORS
    named |= REHEARSAL_DATA | REHEARSAL_SUBMITTERS
    missing = sorted((named | {TRUTH, FAULT_RECORDS}) - set(graph))
    assert not missing, f"the lists name modules that are gone: {missing}"


def test_the_check_sees_the_simulator_imported_into_validation() -> None:
    graph = {
        "server.validation.context": {"sim.loop.session", "sim.world.marsclock"},
        "server.timeline": {"sim.scoring.truth"},
        "server.hub": {"sim.scoring.truth"},
        "server.runtime": {"sim.loop.session"},
        "server.faults.api": {"sim.faults.records"},
        "server.alarms": {"sim.faults.records"},
        "server.rehearsal.risk": {"sim.rehearsal.outcome", "sim.rehearsal.inputs"},
        "server.rehearsal.campaign": {"sim.rehearsal.run"},
        "server.validation.rehearse": {"sim.rehearsal.outcome"},
        "sim.loop.session": {"sim.scoring.truth"},
    }
    assert truth_violations(graph) == [
        "server.alarms -> sim.faults.records",
        "server.rehearsal.campaign -> sim.rehearsal.run",
        "server.timeline -> sim.scoring.truth",
        "server.validation.context -> sim.loop.session",
        "server.validation.rehearse -> sim.rehearsal.outcome",
    ]
