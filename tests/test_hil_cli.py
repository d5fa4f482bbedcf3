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


def test_an_unknown_scenario_is_named_with_the_choices(capsys: pytest.CaptureFixture[str]) -> None:
    from navd.hil.entry import sim

    assert sim(["no-such-mission", "--out", "unused"]) == 2
    err = capsys.readouterr().err
    assert "no scenario named 'no-such-mission'" in err and "claytor-2" in err
    assert "scenarios/" not in err  # not a path inside the installed package


def test_a_missing_sim_extra_is_one_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import builtins
    import sys

    from navd.hil import entry

    real = builtins.__import__

    def without_geographiclib(name: str, *args, **kwargs):  # type: ignore[no-untyped-def]
        if name.startswith("geographiclib"):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return real(name, *args, **kwargs)

    for mod in [m for m in sys.modules if m.startswith(("navd.hil.sim_cli", "navd.hil.world"))]:
        monkeypatch.delitem(sys.modules, mod)
    monkeypatch.setattr(builtins, "__import__", without_geographiclib)
    assert entry.sim(["claytor-2", "--out", "unused"]) == 2
    err = capsys.readouterr().err
    assert err.strip() == "navd-sim: geographiclib is not installed: pip install 'navd[sim]'"
