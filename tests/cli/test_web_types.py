"""``roverops web-types``: the console's committed generated files (the records' JSDoc
typedefs, the LMST reference the JavaScript tests read) equal what it makes from their
sources, the record schemas and the Python Mars clock; a stale one fails here."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from cli.main import main
from cli.web_types import (
    LMST_REFERENCE,
    RECORDS_JS,
    ROOT,
    lmst_reference,
    record_schemas,
    records_js,
    web_types,
)
from sim.loop.downlink import downlink_fields
from sim.scoring.truth import truth_fields
from sim.world.marsclock import MISSIONS, lmst_h_from_t_s, sol_number_t_s


def test_the_committed_generated_files_are_what_the_generator_makes() -> None:
    assert web_types(ROOT, check=True) == []
    assert main(["web-types", "--check"]) == 0


def test_a_stale_file_is_named_and_the_check_writes_nothing(tmp_path: Path) -> None:
    for path in (RECORDS_JS, LMST_REFERENCE):
        (tmp_path / path).parent.mkdir(parents=True)
        shutil.copy(ROOT / path, tmp_path / path)
    stale = (ROOT / RECORDS_JS).read_text(encoding="utf-8").replace(" t_s ", " t ", 1)
    (tmp_path / RECORDS_JS).write_text(stale, encoding="utf-8")
    assert web_types(tmp_path, check=True) == [str(RECORDS_JS)]
    assert (tmp_path / RECORDS_JS).read_text(encoding="utf-8") == stale
    assert web_types(tmp_path, check=False) == [str(RECORDS_JS)]
    assert web_types(tmp_path, check=True) == []


def test_each_record_field_is_a_typedef_property_with_its_described_unit() -> None:
    text = records_js(record_schemas())
    for name, names in (("Downlink", downlink_fields()), ("Truth", truth_fields())):
        block = text.split(f"@typedef {{object}} {name}\n", 1)[1].split(" */", 1)[0]
        props = [line.split("} ", 1)[1].split(" ", 1)[0].strip("[]") for line in block.splitlines()]
        assert props == names
    assert "@property {number|null} position_error_m" in text
    assert '@property {"info"|"warning"|"error"} [severity]' in text
    assert "@property {Array<Event>} [events] what the rover logged" in text


def test_the_lmst_reference_is_the_clock_s_reading_at_each_moment() -> None:
    reference = lmst_reference()
    assert json.loads((ROOT / LMST_REFERENCE).read_text(encoding="utf-8")) == reference
    for sol in reference["sols"]:
        lon_west_deg = MISSIONS[sol["mission"]].lon_west_deg
        for m in sol["moments"]:
            assert int(sol_number_t_s(sol["mission"], m["t_s"])) == sol["sol"] + m["sols_after"]
            hours, minutes, seconds = (int(x) for x in m["text"].split(":"))
            lmst_h = float(lmst_h_from_t_s(m["t_s"], lon_west_deg))
            # half a second past the reading's whole second, to well under a millisecond
            assert abs(lmst_h * 3600 - (hours * 3600 + minutes * 60 + seconds + 0.5)) < 1e-3
