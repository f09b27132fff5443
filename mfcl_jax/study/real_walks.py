"""The simulated walks through the IFC buildings of the real-data results (``study.real``).

Each building names its IFC file and storey and its walks: ``name -> (rooms, waypoints,
note)``, a room sequence (routed through door midpoints by ``sources.walks.route``) or explicit
waypoints in B.
"""

from __future__ import annotations

__all__ = ["OFFICE", "DUPLEX"]

OFFICE = dict(
    building="Office_A",
    file="ifc/Office_A_20110811.ifc",
    storey="Level 1",
    walks={
        "corridor_121": (
            None,
            [(4.0, -13.35), (45.0, -13.35)],
            "straight 41 m corridor: long aperture alias along its axis",
        ),
        "open_office_to_113": (
            ["140 OPEN OFFICE", "121 CORRIDOR", "142 CORRIDOR", "141 CORRIDOR", "113 OPEN OFFICE"],
            None,
            "open office, two corridors, open office: distinctive",
        ),
        "noc_team_room": (
            ["121 CORRIDOR", "153 VEST/ENTRY", "158 NOC", "155 TEAM RM"],
            None,
            "corridor -> vestibule -> NOC -> team room",
        ),
        "offices_141": (
            [
                "141 CORRIDOR",
                "129 CHAPLAIN",
                "141 CORRIDOR",
                "130 SR HR SGT",
                "141 CORRIDOR",
                "131 MESSAGE CENTER",
            ],
            None,
            "in and out of three near-identical small offices on corridor 141",
        ),
    },
)
DUPLEX = dict(
    building="Duplex",
    file="ifc/Duplex_A_20110907_Architecture.ifc",
    storey="Level 1",
    walks={
        # The Living Room - Foyer "door" of each unit lies on an uncut wall in the IFC cut, so
        # walks go through the kitchen.
        "unit_A_tour": (
            [
                "A101 Foyer",
                "A103 Kitchen",
                "A102 Living Room",
                "A103 Kitchen",
                "A101 Foyer",
                "A104 Bathroom 1",
            ],
            None,
            "unit A only; unit B is its 180-degree rotation",
        ),
        "unit_B_tour": (
            [
                "B101 Foyer",
                "B103 Kitchen",
                "B102 Living Room",
                "B103 Kitchen",
                "B101 Foyer",
                "B104 Bathroom 1",
            ],
            None,
            "the same walk in unit B",
        ),
        "unit_A_stair": (
            [
                "A102 Living Room",
                "A103 Kitchen",
                "A101 Foyer",
                "A105 Stair",
                "A101 Foyer",
                "A104 Bathroom 1",
            ],
            None,
            "unit A: living room to stair and bathroom",
        ),
    },
)
