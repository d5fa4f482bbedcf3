from __future__ import annotations

import pytest

from navd import acoustics


def test_mackenzie_published_check_value() -> None:
    # Mackenzie (1981): 1550.744 m/s at 25 degC, 35 ppt, 1000 m
    assert acoustics.mackenzie(25.0, 35.0, 1000.0) == pytest.approx(1550.744, abs=1e-3)


def test_coppens_reduces_to_its_surface_term() -> None:
    # eq. 3.2b at 0 degC, 35 ppt and zero depth is its constant term
    assert acoustics.coppens(0.0, 35.0, 0.0) == pytest.approx(1449.05)
    # fresh water at 10 degC: close to the tabulated 1447 m/s
    assert acoustics.coppens(10.0, 0.0, 0.0) == pytest.approx(1447.3, abs=1.0)


def test_coppens_takes_depth_in_metres() -> None:
    # the equation's own depth unit is km: 1000 m adds about 16.5 m/s
    gain = acoustics.coppens(10.0, 35.0, 1000.0) - acoustics.coppens(10.0, 35.0, 0.0)
    assert 16.0 < gain < 17.0


def test_out_of_range_inputs_warn() -> None:
    assert acoustics.validity_warnings("mackenzie", 10.0, 35.0, 100.0) == []
    w = acoustics.validity_warnings("mackenzie", 10.0, 0.2, 100.0)
    assert len(w) == 1 and "salinity_ppt" in w[0]
    assert acoustics.SoundSpeed(model="coppens", temperature_c=40.0).warnings()


def test_travel_time_with_turnaround() -> None:
    assert acoustics.travel_time_to_range(0.25, 1500.0, 0.05) == pytest.approx(150.0)


def test_modem_range_rescaled_to_water_speed() -> None:
    # the modem assumed 1500 m/s in 1450 m/s water: its ranges read long by 1500/1450
    assert acoustics.rescale_range(150.0, 1500.0, 1450.0) == pytest.approx(145.0)
