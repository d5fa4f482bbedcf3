"""The ``navd`` command line: run, replay, report, watch, capture, calibrate, check-config.

Bad input ends in one line on stderr and exit status 2, never a traceback; a config
error of ``navd run`` exits 78 (EX_CONFIG), on which systemd does not restart it.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import typing
from pathlib import Path

from navd.config import load_config
from navd.formats.mlog import LogError
from navd.settings import ConfigError

if typing.TYPE_CHECKING:
    import asyncio
    from collections.abc import Callable

    from navd.daemon.publish import Command, Publisher
    from navd.settings import Config

#: the modules of optional extras, and the extra that brings each
_EXTRAS = {
    "matplotlib": "report",
    "geographiclib": "report",
    "pyproj": "sim",
    "foxglove": "foxglove",
}
EX_CONFIG = 78  # sysexits.h: a configuration error; navd.service does not restart on it


def _config(args: argparse.Namespace, attr: str = "config") -> Config:
    return load_config(getattr(args, attr), getattr(args, "site", None) or ())


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r:.20}") from None
    if not (v > 0 and v < float("inf")):
        raise argparse.ArgumentTypeError(f"must be more than 0, got {text!r:.20}")
    return v


def _refuse_overwriting(inputs: list[str], outputs: list[str | None]) -> None:
    """No command writes over a file it reads, nor onto a directory: said before
    anything is read."""
    for out in outputs:
        if out is None:
            continue
        if Path(out).is_dir():
            raise ConfigError(f"{out}: is a directory; give a file name to write")
        for given in inputs:
            same = Path(out).resolve() == Path(given).resolve()
            if not same and Path(out).exists() and Path(given).exists():
                same = os.path.samefile(out, given)
            if same:
                raise ConfigError(f"--out {out}: is the input {given}; write elsewhere")


def _cmd_replay(args: argparse.Namespace) -> int:
    from navd.analysis.replay import replay

    if args.each:
        return _replay_each(args)
    if args.jobs is not None or args.scheduler:
        raise ConfigError("--jobs and --scheduler replay several missions: add --each")
    _refuse_overwriting(list(args.input), [args.out])
    cfg = _config(args)
    replay(list(args.input), cfg, args.out, smooth=args.smooth, strict=args.strict)
    return 0


def _replay_each(args: argparse.Namespace) -> int:
    from navd.analysis.jobs import run_all
    from navd.analysis.replay import outputs_for_each, replay_one

    out_dir = Path(args.out)
    if out_dir.exists() and not out_dir.is_dir():
        raise ConfigError(f"--out {out_dir}: with --each, a directory to write the outputs in")
    outs = outputs_for_each(list(args.input), out_dir)
    _refuse_overwriting(list(args.input), [str(o) for o in outs])
    cfg = _config(args)
    out_dir.mkdir(parents=True, exist_ok=True)
    n = len(outs)
    said = run_all(
        replay_one, list(args.input), [cfg] * n, outs, [args.smooth] * n, [args.strict] * n,
        jobs=args.jobs, scheduler=args.scheduler,
    )
    for _, text in said:
        sys.stderr.write(text)
    return 0 if all(ok for ok, _ in said) else 1


def _cmd_report(args: argparse.Namespace) -> int:
    from navd.analysis.report import make_report

    try:
        summary = make_report(args.output, args.out, truth=args.truth, measurements=args.log)
    except (KeyError, TypeError, ValueError) as exc:
        # a line that is JSON but not the output schema (another program's file)
        what = f"{exc.__class__.__name__}: {exc}"[:120]
        print(
            f"navd: report: {args.output}: not a replay output or daemon log ({what})",
            file=sys.stderr,
        )
        return 2
    print(summary)
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    from navd.analysis.export import load_mission
    from navd.formats import gis

    if not (args.gpx or args.kml or args.csv or args.mcap):
        print("navd: export: say what to write: --gpx, --kml, --csv and/or --mcap", file=sys.stderr)
        return 2
    _refuse_overwriting(list(args.log), [args.gpx, args.kml, args.csv, args.mcap])
    mission = load_mission(list(args.log), _config(args), smooth=args.smooth)
    if not mission.estimates:
        print(
            f"navd: export: {args.log[0]}: no estimates (no GPS fix in the log?)", file=sys.stderr
        )
        return 2
    if args.gpx:
        gis.write_gpx(mission, args.gpx)
    if args.kml:
        gis.write_kml(mission, args.kml, args.ellipse_every)
    if args.csv:
        gis.write_csv(mission, args.csv)
    if args.mcap:
        from navd.formats.foxglove_mcap import write_mcap

        counts = write_mcap(mission, args.mcap)
        print(f"{args.mcap}: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    print(
        f"{len(mission.estimates)} estimates, {len(mission.decisions)} range decisions, "
        f"{len(mission.fixes)} GPS fixes, {len(mission.surfacings)} surfacings"
    )
    return 0


def _cmd_foxglove(args: argparse.Namespace) -> int:
    from navd.client import endpoints
    from navd.foxglove_bridge import serve

    z = _config(args).zenoh
    where = endpoints(z.listen, z.connect, args.connect)
    return serve(where, args.host, args.port, args.seconds, args.zenoh_config)


def _cmd_check_config(args: argparse.Namespace) -> int:
    from navd.settings import check_for_run

    cfg = _config(args, "file")
    if not args.offline:
        check_for_run(cfg)  # exactly what navd run refuses
        from navd.daemon.publish import zenoh_config

        zenoh_config(cfg.zenoh)  # the zenoh file opened and parsed as navd run will
    nav = cfg.navigation
    lines = [f"{' + '.join([args.file, *(args.site or [])])}: ok"]
    lines.append(
        f"  filter mode {nav.filter}, {nav.rate_hz:g} Hz, "
        f"declination {nav.magnetic_declination_deg:+g} deg"
    )
    lines.append(
        f"  speed map {nav.speed.rpm_per_mps:g} RPM per m/s; sound speed {nav.sound_speed.model}"
    )
    for name, b in cfg.beacons.items():
        where = f"{b.lat}, {b.lon}" if b.lat is not None else "position from replies only"
        lines.append(
            f"  beacon {name}: {where}, depth {b.depth:g} m, turnaround {b.turnaround_s:g} s"
        )
    tide = nav.tide
    if tide.amplitude_mps > 0.0:
        lines.append(
            f"  tidal prediction: {tide.amplitude_mps:g} m/s toward {tide.toward_deg:g} deg at "
            f"maximum flood, {tide.max_flood_utc}, period {tide.period_s / 3600.0:.2f} h, "
            f"off by up to {tide.error_fraction:.0%} of its speed"
        )
        if nav.filter != "default":
            lines.append(f"  warning: the {nav.filter} mode does not use the tidal prediction")
    lines += [f"  warning: {w}" for w in nav.sound_speed.model_obj().warnings()]
    if not args.merged:
        print("\n".join(lines))
        return 0
    import dataclasses

    import yaml

    # every key as navd will use it (the file, its overlays and sites, the defaults), as
    # YAML a config can be: the summary above it as comments
    print("\n".join(f"# {line}" for line in lines))
    print(yaml.safe_dump(dataclasses.asdict(cfg), sort_keys=False), end="")
    return 0


#: logging's levels as syslog priorities, which journald reads from a ``<N>`` prefix
_PRIORITY = {logging.CRITICAL: 2, logging.ERROR: 3, logging.WARNING: 4, logging.INFO: 6}


class _JournalFormatter(logging.Formatter):
    """``<N>`` before each line: under systemd, ``journalctl -p warning`` then finds
    every warning (sd-daemon(3), "SD_WARNING")."""

    def format(self, record: logging.LogRecord) -> str:
        text = super().format(record)
        prio = _PRIORITY.get(record.levelno, 7 if record.levelno < logging.INFO else 3)
        return "\n".join(f"<{prio}>{line}" for line in text.splitlines())


def _log_to_stderr(env: typing.Mapping[str, str]) -> None:
    """The daemon's log lines on stderr, with journald priorities when systemd reads it."""
    handler = logging.StreamHandler()
    fmt = "%(levelname)s %(name)s: %(message)s"
    # JOURNAL_STREAM is set by systemd when stderr is the journal (systemd.exec(5))
    journal = bool(env.get("JOURNAL_STREAM"))
    handler.setFormatter(_JournalFormatter(fmt) if journal else logging.Formatter(fmt))
    logging.basicConfig(level=logging.INFO, handlers=[handler])


def _cmd_run(args: argparse.Namespace) -> int:
    import asyncio
    import signal

    from navd.config import default_config_path
    from navd.daemon.daemon import Daemon
    from navd.daemon.publish import Publisher, zenoh_config
    from navd.settings import check_for_run

    try:
        args.config = args.config or default_config_path(os.environ)
        if args.config is None:
            raise ConfigError("--config: required (outside systemd's ConfigurationDirectory)")
        cfg = _config(args)
        check_for_run(cfg)
        zenoh_config(cfg.zenoh)  # a file zenoh cannot use is a config error, said now
    except ConfigError as exc:
        print(f"navd: {exc}", file=sys.stderr)
        return EX_CONFIG
    _log_to_stderr(os.environ)

    def publisher(
        loop: asyncio.AbstractEventLoop, on_command: Callable[[Command], str | None]
    ) -> Publisher:
        return Publisher(cfg.zenoh, cfg.vehicle.name, loop, on_command)

    async def main() -> None:
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGTERM, signal.SIGINT):
            loop.add_signal_handler(sig, stop.set)
        daemon = Daemon(cfg, publisher_factory=publisher)
        await daemon.run(stop)
        logging.getLogger("navd").info("stopped; log %s", daemon.rlog.path or "(nothing written)")

    asyncio.run(main())
    return 0


def _cmd_watch(args: argparse.Namespace) -> int:
    from navd.watch import watch, watch_fleet

    if args.fleet:
        return watch_fleet(
            _config(args), args.seconds, args.every, args.connect, args.zenoh_config
        )
    return watch(
        _config(args), args.count, args.seconds, args.every, args.connect, args.zenoh_config
    )


def _cmd_capture(args: argparse.Namespace) -> int:
    from navd.daemon.capture import capture

    _log_to_stderr(os.environ)
    path = capture(_config(args), args.device, args.seconds, args.out)
    if path is None:
        print(f"navd: capture: nothing written (did devices.{args.device}.port open?)")
        return 1
    print(path)
    return 0


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from navd.analysis.calibrate import CalibrationError, fit, stretches, supports_offset
    from navd.formats.mlog import read_measurement_log

    _refuse_overwriting(list(args.log), [args.out])

    cfg = _config(args)
    nav = cfg.navigation
    records = [r for path in args.log for r in read_measurement_log(path).records]
    records.sort(key=lambda r: r.t)
    runs = stretches(records, args.window)
    try:
        if args.what == "compass":
            f = fit(runs, nav.magnetic_declination_deg, nav.speed.rpm_per_mps)
        else:
            f = fit(
                runs,
                nav.magnetic_declination_deg,
                nav.speed.rpm_per_mps,
                deviation=nav.compass_deviation_deg,
                fit_deviation=False,
                fit_offset=supports_offset(runs),
            )
    except CalibrationError as exc:
        print(f"navd: calibrate {args.what}: {exc}", file=sys.stderr)
        return 2
    print(
        f"{f.stretches} straight surface stretches, headings over {f.coverage_deg:.0f} deg; "
        f"residual {f.residual_deg:.2f} deg, {f.residual_mps:.3f} m/s; "
        f"current {f.current_n:+.3f} N {f.current_e:+.3f} E m/s"
    )
    if args.what == "compass":
        for name, c, sd in zip("ABCDE", f.deviation_deg, f.deviation_std_deg, strict=True):
            print(f"  {name} {c:+7.2f} +- {sd:.2f} deg")
        snippet = "navigation:\n  compass_deviation_deg: [{}]\n".format(
            ", ".join(f"{c:.3f}" for c in f.deviation_deg)
        )
    else:
        print(f"  rpm_per_mps {f.rpm_per_mps:.1f} +- {f.rpm_per_mps_std:.1f}")
        print(f"  offset_mps {f.offset_mps:+.3f} +- {f.offset_std_mps:.3f}")
        snippet = (
            "navigation:\n  speed:\n"
            f"    rpm_per_mps: {f.rpm_per_mps:.1f}\n    offset_mps: {f.offset_mps:.3f}\n"
        )
    if args.out:
        with open(args.out, "w", encoding="utf-8") as fh:
            fh.write(snippet)
        print(f"wrote {args.out}")
    else:
        print(snippet, end="")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="navd", description="AUV navigation daemon and tools")
    p.add_argument("--version", action="version", version=f"navd {_version()}")
    sub = p.add_subparsers(dest="cmd", metavar="COMMAND")

    r = sub.add_parser("replay", help="run the navigation filter over a recorded log")
    r.add_argument(
        "input",
        nargs="+",
        help="measurement log (JSON Lines, navd-measurements v1); the files of a rotated "
        "daemon log may be given in order",
    )
    r.add_argument("--config", help="configuration YAML (defaults if omitted)")
    _site_option(r)
    r.add_argument("--out", required=True, help="output JSON Lines")
    r.add_argument("--smooth", action="store_true", help="add an RTS smoothing pass")
    r.add_argument("--strict", action="store_true", help="the first malformed line is fatal")
    r.add_argument(
        "--each",
        action="store_true",
        help="every input is a mission of its own; --out is then a directory",
    )
    r.add_argument(
        "--jobs", type=int, metavar="N", help="with --each: worker processes (default: the cores)"
    )
    r.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="with --each: run on this Dask scheduler's workers (tcp://host:8786)",
    )
    r.set_defaults(func=_cmd_replay)

    rep = sub.add_parser("report", help="figures and summary of a replay output")
    rep.add_argument("output", help="replay output JSON Lines")
    rep.add_argument("--truth", help="truth JSON Lines from navd-sim")
    rep.add_argument("--log", help="the measurement log (for GPS fixes)")
    rep.add_argument("--out", required=True, help="directory for the figures and summary")
    rep.set_defaults(func=_cmd_report)

    run = sub.add_parser("run", help="run the daemon on the vehicle's serial devices")
    run.add_argument(
        "--config",
        help="configuration YAML (default under systemd: $CONFIGURATION_DIRECTORY/navd.yaml; "
        "the log goes to log.dir, else $LOGS_DIRECTORY, else ./navd-log)",
    )
    _site_option(run)
    run.set_defaults(func=_cmd_run)

    w = sub.add_parser("watch", help="print the live estimate published over zenoh")
    w.add_argument("--config", help="the daemon's config (vehicle name, zenoh endpoints)")
    _site_option(w)
    w.add_argument("--count", type=int, help="stop after this many estimates")
    w.add_argument("--seconds", type=float, help="stop after this long")
    w.add_argument("--every", type=float, default=1.0, help="print at most every N s (0: all)")
    w.add_argument(
        "--fleet", action="store_true", help="every vehicle under auv/*, and which are alive"
    )
    _connect_option(w)
    w.set_defaults(func=_cmd_watch)

    cap = sub.add_parser(
        "capture",
        help="record every byte one device sends, asked as navd asks it in service",
    )
    cap.add_argument("device", help="ahrs, gps, pressure, motor or modem")
    cap.add_argument("--config", required=True, help="the vehicle's config (the port)")
    _site_option(cap)
    cap.add_argument("--seconds", type=float, default=30.0, help="how long (default 30)")
    cap.add_argument("--out", required=True, help="directory for the capture log")
    cap.set_defaults(func=_cmd_capture)

    cal = sub.add_parser(
        "calibrate",
        help="fit the compass deviation curve or the RPM map from surface runs with GPS",
    )
    cal.add_argument("what", choices=["compass", "speed"])
    cal.add_argument("log", nargs="+", help="measurement or daemon log(s) with the surface runs")
    cal.add_argument("--config", help="the vehicle's config (declination, current speed map)")
    _site_option(cal)
    cal.add_argument(
        "--window", type=float, default=120.0, help="longest straight run per stretch (s)"
    )
    cal.add_argument("--out", help="write the config snippet here (else printed)")
    cal.set_defaults(func=_cmd_calibrate)

    ex = sub.add_parser("export", help="a mission as GPX, KML, CSV (GIS tools) or MCAP (Foxglove)")
    ex.add_argument("log", nargs="+", help="measurement or daemon log(s), in order")
    ex.add_argument("--config", help="configuration YAML (defaults if omitted)")
    _site_option(ex)
    ex.add_argument("--smooth", action="store_true", help="also the RTS-smoothed track")
    ex.add_argument("--gpx", metavar="OUT", help="tracks and surfacing points as GPX 1.1")
    ex.add_argument("--kml", metavar="OUT", help="tracks, surfacings, 95 %% ellipses as KML")
    ex.add_argument("--csv", metavar="OUT", help="one row per estimate")
    ex.add_argument("--mcap", metavar="OUT", help="MCAP with Foxglove schemas (navd[foxglove])")
    ex.add_argument(
        "--ellipse-every",
        type=_positive,
        default=60.0,
        help="KML: a 95 %% ellipse every N s (more than 0)",
    )
    ex.set_defaults(func=_cmd_export)

    fg = sub.add_parser(
        "foxglove", help="serve every vehicle's navigation to Foxglove, live (navd[foxglove])"
    )
    fg.add_argument("--config", help="a config whose zenoh endpoints to connect to")
    _site_option(fg)
    _connect_option(fg)
    fg.add_argument("--host", default="127.0.0.1", help="address to serve on (default 127.0.0.1)")
    fg.add_argument("--port", type=int, default=8765, help="WebSocket port (default 8765)")
    fg.add_argument("--seconds", type=float, help="stop after this long")
    fg.set_defaults(func=_cmd_foxglove)

    c = sub.add_parser(
        "check-config", help="validate a configuration as navd run would, and explain it"
    )
    c.add_argument("file", help="configuration YAML (its overlays are read too)")
    _site_option(c)
    c.add_argument(
        "--offline",
        action="store_true",
        help="for replay only: do not require the device ports navd run needs",
    )
    c.add_argument(
        "--merged",
        action="store_true",
        help="also print the merged result (overlays, sites and defaults) as YAML",
    )
    c.set_defaults(func=_cmd_check_config)
    return p


def _connect_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--connect",
        action="append",
        metavar="ENDPOINT",
        help="zenoh endpoint (a vehicle, or a router for a fleet), e.g. tcp/10.0.0.1:7447; "
        "else the config's zenoh.connect, else its zenoh.listen",
    )
    p.add_argument(
        "--zenoh-config",
        metavar="FILE",
        help="this tool's own zenoh JSON5 file: its user and password under the vehicle's "
        "access control, or TLS (config/zenoh-client.json5)",
    )


def _site_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--site",
        action="append",
        metavar="FILE",
        help="a site overlay (e.g. config/sites/claytor-lake.yaml) on top of the config; "
        "may be repeated",
    )


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("navd")
    except PackageNotFoundError:
        return "unknown (not installed)"


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.cmd is None:  # no command: what there is to do, not an argparse complaint
        parser.print_help()
        return 2
    try:
        rc: int = args.func(args)
        return rc
    except (ConfigError, LogError) as exc:
        print(f"navd: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        return 0
    except ModuleNotFoundError as exc:  # an optional extra (report, sim) not installed
        module = (exc.name or "").split(".")[0]
        extra = _EXTRAS.get(module)
        if extra is None:
            raise
        print(f"navd: {module} is not installed: pip install 'navd[{extra}]'", file=sys.stderr)
        return 2
    except OSError as exc:
        name = getattr(exc, "filename", None) or ""
        print(f"navd: {name}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
