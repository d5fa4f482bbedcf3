"""navd-hil refuses a bad fault schedule with one line naming the entry, before starting."""

from __future__ import annotations

from pathlib import Path

import pytest

from navd.hil.runner import main


@pytest.mark.parametrize(
    ("schedule", "named"),
    [
        ("{t: 1}", "faults: expected a list"),
        ("[{device: gps, action: stall}]", "faults[0].t"),
        (
            "[{t: 1, device: gps, action: stall}, {t: .nan, device: gps, action: stall}]",
            "faults[1].t",
        ),
        ("[{t: 1, device: sonar, action: stall}]", "faults[0].device"),
        ("[{t: 1, device: gps, action: explode}]", "faults[0].action"),
        ("[{t: 1, device: gps, action: garbage, value: 3}]", "faults[0].value"),
        ("[{t: 1, device: gps, action: garbage, value: yes}]", "faults[0].value"),
    ],
)
def test_bad_fault_schedule_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], schedule: str, named: str
) -> None:
    f = tmp_path / "faults.yaml"
    f.write_text(schedule)
    assert main(["demo", "--dir", str(tmp_path / "v"), "--faults", str(f)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and named in err and "Traceback" not in err
