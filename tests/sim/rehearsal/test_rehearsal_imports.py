"""A rehearsal reads only its inputs: it imports nothing of the server, the benches or the CLI,
and of the scoring only what ``RoverSession`` itself imports.

``sim.loop.session`` builds each frame's truth record beside the downlink
(``sim.loop.frames`` -> ``sim.scoring.scorer``, ``sim.scoring.truth``; the session's
``CommandReport`` carries the scores): a rehearsal's own sampled rover makes them, and
reads of them only an HGA pass's true margin (its sampled world's truth). Nothing else of
``sim.scoring`` may come in with ``sim.rehearsal``.
"""

from __future__ import annotations

import json
import subprocess
import sys

FORBIDDEN = ("server", "bench", "cli", "sim.scoring")


def _imported(module: str) -> set[str]:
    code = (
        f"import json, sys, {module}\n"
        f"print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in "
        f"('server', 'bench', 'cli') or m.startswith('sim.scoring'))))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return set(json.loads(out.stdout))


def test_rehearsal_imports_no_server_bench_cli_nor_more_scoring_than_the_session() -> None:
    rehearsal = _imported("sim.rehearsal.run")
    session = _imported("sim.loop.session")
    assert not any(m.split(".")[0] in FORBIDDEN[:3] for m in rehearsal)
    assert rehearsal <= session
    assert "sim.scoring.scorer" in session  # the reason there is any: the frames' truth
