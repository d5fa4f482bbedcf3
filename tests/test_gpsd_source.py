"""gpsd as the GPS source: a real gpsd, fed a real receiver's capture by gpsfake.

``devices.gps.source: gpsd`` must give the filter the same fixes the serial NMEA
decoder gives from the same bytes (positions, heights), through the same device.
gpsd and gpsfake come from Debian's gpsd and gpsd-clients (.ci/run installs them).
"""

from __future__ import annotations

import asyncio
import shutil
import subprocess
import time
from pathlib import Path

import pytest
from conftest import DeviceHost

from navd.daemon.devices.gps import GpsReceiver
from navd.drivers.gps import NmeaDecoder
from navd.drivers.gpsd import GpsdDecoder
from navd.drivers.transport import SerialTransport
from navd.hil.bench_vehicle import free_port
from navd.records import Gps
from navd.settings import GpsDevice

CAPTURE = Path(__file__).parent / "data" / "gpsd" / "ch-4711.log"

pytestmark = pytest.mark.skipif(
    shutil.which("gpsfake") is None or shutil.which("gpsd") is None,
    reason="gpsd and gpsfake (Debian: gpsd, gpsd-clients) are not installed",
)


def test_gpsd_source_gives_the_serial_decoders_fixes() -> None:
    port = free_port()
    fake = subprocess.Popen(
        ["gpsfake", "-q", "-1", "-P", str(port), "-c", "0.1", str(CAPTURE)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    host = DeviceHost()
    cfg = GpsDevice(source="gpsd", gpsd_port=port)
    dev = GpsReceiver(cfg, host)  # type: ignore[arg-type]

    async def main() -> None:
        tr = SerialTransport(cfg.url, 9600, dev.decoder, dev.handle, on_open=dev.on_open)
        dev.transport = tr
        tr.start()
        deadline = time.monotonic() + 30.0

        def lost_fix_after_fixes() -> bool:  # the capture's end: its receiver loses the fix
            fixes = [r.fix for r in host.fed if isinstance(r, Gps)]
            return 1 in fixes and fixes[-1] == 0

        while time.monotonic() < deadline and not lost_fix_after_fixes():
            await asyncio.sleep(0.2)
        await tr.stop()

    try:
        asyncio.run(main())
    finally:
        fake.terminate()
        fake.wait(10)

    assert cfg.url == f"socket://127.0.0.1:{port}"
    got = [r for r in host.fed if isinstance(r, Gps) and r.lat is not None]
    serial = [r for r in NmeaDecoder().feed(CAPTURE.read_bytes(), 0.0) if isinstance(r, Gps)]
    serial = [r for r in serial if r.lat is not None]
    assert len(got) >= 5, host.fed
    assert isinstance(dev.decoder, GpsdDecoder)
    assert dev.decoder.stats.bad_frame == 0
    for rec in got:
        match = [
            s for s in serial if abs(s.lat - rec.lat) < 1e-7 and abs(s.lon - rec.lon) < 1e-7
        ]
        assert match, rec
        assert rec.fix == match[0].fix
        if rec.alt is None:
            continue  # gpsd may report an epoch from its RMC before its GGA: no height yet
        assert rec.alt == pytest.approx(match[0].alt, abs=0.01)  # altHAE: MSL + separation
        assert rec.alt_msl == pytest.approx(match[0].alt_msl, abs=0.01)
    assert sum(r.alt is not None for r in got) >= len(got) // 2
    # the receiver lost its fix at the end of the capture: gpsd says mode 1, navd "no fix"
    assert any(isinstance(r, Gps) and r.fix == 0 for r in host.fed)
