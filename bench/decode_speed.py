"""``make bench-decode``: decoding cost per device, and what it costs at the device's rate.

Each decoder is fed one frame per ``feed`` call (as serial reads arrive at these
rates), frames made by the device's emulator, 20,000 frames per device; the best of
three runs counts.  CPU share = (seconds per record) x (records per second on the
vehicle) x 100.
"""

from __future__ import annotations

import argparse
import asyncio
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bench.common import report
from navd.drivers import ahrs, castle, gps, keller, modem
from navd.hil.emulators.ahrs import AhrsEmulator
from navd.hil.emulators.gps import GpsEmulator

N = 20_000


def _frames(tmp: Path) -> dict[str, tuple[Callable[[], Any], list[bytes], float]]:
    async def make() -> tuple[bytes, bytes]:
        a = AhrsEmulator(tmp / "a")
        a.roll_deg, a.pitch_deg, a.yaw_deg = 1.0, -2.0, 123.0
        g = GpsEmulator(tmp / "g")
        g.lat, g.lon, g.alt_msl = 37.05, -80.66, 560.0
        out = a.euler_frame(), g.gga() + g.rmc()
        a.close()
        g.close()
        return out

    euler, nmea = asyncio.run(make())
    k = bytes.fromhex("fa 49 3f c0 00 00 00 53 67")
    c = bytes.fromhex("03 e8 15")
    m = b"Range 1 to 2 : 153.4 m\r\nRemote Lat: 37.0490112 Lon: -80.6670001 Depth: 3.0\r\nOK\r\n"
    return {
        # name: (decoder factory, frames, vehicle rate in records/s)
        "AHRS 3DM-GX3-25 (Euler)": (ahrs.AhrsDecoder, [euler] * N, 100.0),
        "GPS NMEA (GGA+RMC)": (gps.NmeaDecoder, [nmea] * (N // 4), 2.0),
        "Keller PA-30X (F73)": (lambda: keller.KellerDecoder(250), [k] * N, 10.0),
        "Castle RPM": (castle.CastleDecoder, [c] * N, 10.0),
        "Benthos ATRX reply": (modem.ModemDecoder, [m] * (N // 4), 0.1),
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--write", help="BENCHMARKS.md to update")
    args = p.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, (make, frames, rate) in _frames(Path(tmp)).items():
            best = float("inf")
            for _ in range(3):
                dec = make()
                t0 = time.perf_counter()
                n = 0
                for f in frames:
                    # answers are matched to requests, so each frame is asked for first
                    if isinstance(dec, keller.KellerDecoder):
                        dec.request(keller.CH_PRESSURE)
                    elif isinstance(dec, castle.CastleDecoder):
                        dec.request_rpm()
                    n += len(dec.feed(f, 0.0))
                best = min(best, (time.perf_counter() - t0) / n)
            share = best * rate * 100
            rows.append(f"| {name} | {1 / best:,.0f} | {best * 1e6:.1f} | {rate:g} | {share:.3f} |")
    body = "\n".join(
        [
            f"One frame per `feed` call, {N:,} frames per device (fewer for text devices), "
            "best of 3; Keller and Castle include encoding the request each answer matches.",
            "",
            "| device | records/s | us/record | vehicle rate (Hz) | % of one core at that rate |",
            "|---|---|---|---|---|",
            *rows,
            "",
            "Target: the AHRS at 100 Hz well under 1 % of a core.",
        ]
    )
    report(body, args.write, "bench-decode", "Decoding cost")
    return 0


if __name__ == "__main__":
    sys.exit(main())
