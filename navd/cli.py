"""The ``navd`` command line: replay, report, check-config.

Bad input ends in one line on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import sys

from navd.config import ConfigError, load_config
from navd.mlog import LogError


def _cmd_replay(args: argparse.Namespace) -> int:
    from navd.replay import replay

    cfg = load_config(args.config)
    replay(args.input, cfg, args.out, smooth=args.smooth, strict=args.strict)
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from navd.report import make_report

    summary = make_report(args.output, args.out, truth=args.truth, measurements=args.log)
    print(summary)
    return 0


def _cmd_check_config(args: argparse.Namespace) -> int:
    cfg = load_config(args.file)
    nav = cfg.navigation
    print(f"{args.file}: ok")
    print(
        f"  filter mode {nav.filter}, {nav.rate_hz:g} Hz, "
        f"declination {nav.magnetic_declination_deg:+g} deg"
    )
    print(f"  speed map {nav.speed.rpm_per_mps:g} RPM per m/s; sound speed {nav.sound_speed.model}")
    for name, b in cfg.beacons.items():
        where = f"{b.lat}, {b.lon}" if b.lat is not None else "position from replies only"
        print(f"  beacon {name}: {where}, depth {b.depth:g} m, turnaround {b.turnaround_s:g} s")
    for w in nav.sound_speed.model_obj().warnings():
        print(f"  warning: {w}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="navd", description="AUV navigation daemon and tools")
    sub = p.add_subparsers(dest="cmd", required=True)

    r = sub.add_parser("replay", help="run the navigation filter over a recorded log")
    r.add_argument("input", help="measurement log (JSON Lines, navd-measurements v1)")
    r.add_argument("--config", help="configuration YAML (defaults if omitted)")
    r.add_argument("--out", required=True, help="output JSON Lines")
    r.add_argument("--smooth", action="store_true", help="add an RTS smoothing pass")
    r.add_argument("--strict", action="store_true", help="the first malformed line is fatal")
    r.set_defaults(func=_cmd_replay)

    rep = sub.add_parser("report", help="figures and summary of a replay output")
    rep.add_argument("output", help="replay output JSON Lines")
    rep.add_argument("--truth", help="truth JSON Lines from navd-sim")
    rep.add_argument("--log", help="the measurement log (for GPS fixes)")
    rep.add_argument("--out", required=True, help="directory for the figures and summary")
    rep.set_defaults(func=_cmd_report)

    c = sub.add_parser("check-config", help="validate a configuration file and explain it")
    c.add_argument("file")
    c.set_defaults(func=_cmd_check_config)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (ConfigError, LogError) as exc:
        print(f"navd: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        return 0
    except OSError as exc:
        name = getattr(exc, "filename", None) or ""
        print(f"navd: {name}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
