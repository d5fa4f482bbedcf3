"""``navd watch``: the live estimate for a person, and the example for autopilot writers.

It is a zenoh peer that connects to the daemon's endpoints (it listens on none),
subscribes to ``auv/<vehicle>/nav/estimate`` and ``.../range``, and prints a line
per estimate.  Callbacks run on zenoh threads; a ring channel keeps only the newest
samples if the printer falls behind.
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace

import zenoh

from navd.config import Config
from navd.daemon.publish import zenoh_config
from navd.formats import jsonlines


def format_estimate(e: dict) -> str:
    return (
        f"{e.get('mode', '?'):9s} {e['lat']:11.7f} {e['lon']:12.7f} depth {e['depth']:5.2f} m  "
        f"1-sigma {e['std_n']:5.1f}/{e['std_e']:5.1f} m  current "
        f"{e['current_n']:+.2f}N {e['current_e']:+.2f}E m/s  seq {e.get('seq')}"
    )


def watch(cfg: Config, count: int | None, seconds: float | None, every: float) -> int:
    z = cfg.zenoh
    # connect to where the daemon listens; listen nowhere ourselves
    zc = replace(z, listen=[], connect=list(z.connect) or list(z.listen))
    session = zenoh.open(zenoh_config(zc))
    prefix = f"auv/{cfg.vehicle.name}/nav"
    est_sub = session.declare_subscriber(f"{prefix}/estimate", zenoh.handlers.RingChannel(64))
    rng_sub = session.declare_subscriber(f"{prefix}/range", zenoh.handlers.RingChannel(64))
    n = 0
    last_print = 0.0
    t_end = time.monotonic() + seconds if seconds else None
    try:
        while (count is None or n < count) and (t_end is None or time.monotonic() < t_end):
            got = False
            while (s := rng_sub.try_recv()) is not None:
                r = jsonlines.loads(s.payload.to_bytes())
                verdict = "accepted" if r.get("accepted") else f"rejected ({r.get('reason')})"
                print(f"range {r.get('range_m', float('nan')):.1f} m {verdict}", flush=True)
            while (s := est_sub.try_recv()) is not None:
                got = True
                n += 1
                e = jsonlines.loads(s.payload.to_bytes())
                now = time.monotonic()
                if every <= 0 or now - last_print >= every:
                    print(format_estimate(e), flush=True)
                    last_print = now
                if count is not None and n >= count:
                    break
            if not got:
                time.sleep(0.02)
    except KeyboardInterrupt:
        pass
    finally:
        session.close()
    if n == 0:
        print("navd watch: no estimate received", file=sys.stderr)
        return 1
    return 0
