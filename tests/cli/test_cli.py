"""The ``roverops`` command line: real runs and every kind of bad input."""

import json
import subprocess
import sys

import pytest

from cli.main import main


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    try:
        code = main(list(argv))
    except SystemExit as exit_:  # argparse's own usage errors
        code = int(exit_.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def test_ephem_json_has_the_documented_sections(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = _run(
        capsys,
        "ephem",
        "--utc",
        "2004-01-03T13:46:31",
        "--lat-deg",
        "-14.64",
        "--lon-west-deg",
        "184.702",
        "--mission",
        "spirit",
        "--json",
    )
    assert code == 0
    result = json.loads(out)
    assert {"msd", "mst_h", "lmst_h", "ltst_h", "ls_deg", "sol"} <= set(result)
    assert 180.0 < result["one_way_light_time_s"] < 1340.0  # 3 to 22 min 20 s
    for section in ("mars24", "truth", "ivp"):
        assert {"sun_elev_deg", "sun_azimuth_deg"} <= set(result[section])
    # the night side at the Spirit site 18 h before landing: the Sun is down in all three
    assert all(result[s]["sun_elev_deg"] < 0 for s in ("mars24", "truth", "ivp"))


@pytest.mark.parametrize(
    ("argv", "parameter"),
    [
        (["ephem", "--utc", "2004-13-03", "--lat-deg", "0", "--lon-west-deg", "0"], "utc"),
        (["ephem", "--utc", "yesterday", "--lat-deg", "0", "--lon-west-deg", "0"], "utc"),
        (["ephem", "--utc", "2090-01-01T00:00:00", "--lat-deg", "0", "--lon-west-deg", "0"], "utc"),
        (
            ["ephem", "--utc", "2004-01-03T00:00:00", "--lat-deg", "95", "--lon-west-deg", "0"],
            "lat",
        ),
        (["ephem", "--utc", "2004-01-03T00:00:00", "--lat-deg", "x", "--lon-west-deg", "0"], "lat"),
        (
            [
                "ephem",
                "--utc",
                "2004-01-03T00:00:00",
                "--lat-deg",
                "0",
                "--lon-west-deg",
                "0",
                "--mission",
                "curiosity",
            ],
            "mission",
        ),
        (["run", "--scenario", "moonwalk"], "scenario"),
        (["run", "--scenario", "drive_100m", "--site", "olympus"], "site"),
        (["run", "--scenario", "drive_100m", "--distance-m", "-5"], "distance_m"),
        (["run", "--scenario", "drive_100m", "--distance-m", "nan"], "distance-m"),
        (["run", "--scenario", "rest_1h", "--distance-m", "5"], "distance_m"),
        (["run", "--scenario", "rest_1h", "--seed", "-1"], "seed"),
        (["run", "--scenario", "drive_100m", "--site", ""], "site"),
        (["run", "--scenario", "rest_1h", "--duration-s", "1e-300"], "duration_s"),
        (["run", "--scenario", "turn_360_eq22", "--angle-deg", "3600"], "angle_deg"),
        (["run", "--scenario", "drive_100m", "--distance-m", "1e-300"], "distance_m"),
        (
            ["ephem", "--utc", "2004-12-31T23:59:60", "--lat-deg", "0", "--lon-west-deg", "0"],
            "leap",
        ),
        (["bench", "warp"], "name"),
    ],
)
def test_bad_input_names_the_parameter_and_exits_non_zero(
    capsys: pytest.CaptureFixture[str], argv: list[str], parameter: str
) -> None:
    code, out, err = _run(capsys, *argv)
    assert code != 0
    assert parameter in err
    assert "Traceback" not in err and out == ""


def test_console_script_reports_errors_without_traceback() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "cli.main", "run", "--scenario", "nowhere"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 2
    assert "scenario" in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["serve", "--port", "0"], "--port must be in 1-65535"),
        (["serve", "--port", "http"], "--port must be an integer"),
        (["serve", "--operator-token", "short"], "--operator-token"),
        (["serve", "--truth-view", "nobody"], "--truth-view must be everyone or conductor"),
    ],
)
def test_serve_refuses_bad_arguments_before_starting(
    capsys: pytest.CaptureFixture[str], argv: list[str], needle: str
) -> None:
    code, _, err = _run(capsys, *argv)
    assert code == 2 and needle in err and "Traceback" not in err


def test_serve_refuses_a_wrong_truth_view_from_the_environment(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("ROVEROPS_TRUTH_VIEW", "operators")
    code, _, err = _run(capsys, "serve")
    error_lines = [line for line in err.splitlines() if "error" in line]
    assert code == 2 and "Traceback" not in err
    assert error_lines == [
        "roverops serve: error: argument --truth-view: --truth-view must be everyone or "
        "conductor, got 'operators'"
    ]
