"""Bad input never ends in a traceback or a NaN: the log reader, the config loader, the filter."""

from __future__ import annotations

import json
import math

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from serialised import rows

from navd.filter import Navigator
from navd.formats.mlog import Skipped, iter_lines
from navd.records import Record
from navd.settings import ConfigError, config_from_dict

numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(10**6), 10**6),
    st.sampled_from([0, 1, 2, -1, 1e308, -0.0]),
)
values = st.one_of(
    numbers, st.none(), st.booleans(), st.text(max_size=5), st.lists(numbers, max_size=2)
)
TYPES = [
    "heading",
    "attitude",
    "rpm",
    "depth",
    "pressure",
    "gps",
    "range",
    "travel_time",
    "velocity",
    "clock",
    "bogus",
]
FIELDS = [
    "deg",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "rpm",
    "m",
    "bar",
    "lat",
    "lon",
    "alt",
    "fix",
    "hdop",
    "t_ping",
    "beacon",
    "beacon_lat",
    "beacon_lon",
    "beacon_depth",
    "twtt_s",
    "u",
    "v",
    "w",
    "utc_s",
]
records = st.fixed_dictionaries(
    {"type": st.sampled_from(TYPES), "t": st.one_of(st.floats(0, 100), st.floats(0, 1e6), numbers)},
    optional={f: values for f in FIELDS},
)
# a line's type as a hostile or broken writer may give it: no string at all (a list or an
# object is no key of any table); a daemon log's own types are passed over, not skipped
any_type = st.one_of(
    st.sampled_from([*TYPES, "cmd_resume", "cmd_beacon"]),
    values,
    st.dictionaries(st.text(max_size=3), numbers, max_size=2),
)
typed_lines = st.fixed_dictionaries({"type": any_type, "t": numbers}).map(
    lambda o: json.dumps(o, allow_nan=True)
)


def _line(obj: dict) -> str:
    return json.dumps(obj, allow_nan=True)


lines = st.one_of(
    records.map(_line),
    typed_lines,
    records.map(_line).map(lambda s: s[: len(s) // 2]),  # truncated
    st.text(max_size=40),
    st.binary(max_size=40).map(lambda b: b.decode("latin-1")),
)


@given(st.lists(lines, max_size=30))
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_log_reader_never_raises_and_counts_every_bad_line(raw: list[str]) -> None:
    items = list(iter_lines(raw))
    nonblank = sum(1 for x in raw if x.strip() and "\n" not in x.strip())
    assert len(items) <= len(raw)
    for _, item in items:
        assert isinstance(item, Skipped | Record)
    if all("\n" not in x for x in raw):
        assert len(items) == nonblank


def test_a_line_whose_type_is_no_string_is_skipped_by_number() -> None:
    items = list(iter_lines(['{"type": [1], "t": 1.0}', '{"type": {"a": 1}, "t": 2.0}']))
    assert [(no, type(item)) for no, item in items] == [(2, Skipped), (3, Skipped)]


@given(st.lists(records, max_size=60))
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_filter_never_publishes_nan(objs: list[dict]) -> None:
    seed = ['{"type":"gps","t":0,"lat":37.05,"lon":-80.66,"alt":0,"fix":1}']
    recs = [
        it for _, it in iter_lines(seed + [_line(o) for o in objs]) if not isinstance(it, Skipped)
    ]
    nav = Navigator(config_from_dict({}))
    out = []
    for r in recs:
        out.extend(nav.feed(r))
    if recs:
        out.extend(nav.advance(recs[-1].t))
    for o in rows(out):
        for v in o.values():
            if isinstance(v, float):
                assert math.isfinite(v)


config_values = st.recursive(
    st.one_of(numbers, st.none(), st.booleans(), st.text(max_size=8)),
    lambda inner: st.one_of(
        st.lists(inner, max_size=3), st.dictionaries(st.text(max_size=8), inner, max_size=3)
    ),
    max_leaves=8,
)
config_docs = st.one_of(
    config_values,
    st.fixed_dictionaries(
        {},
        optional={
            "navigation": st.dictionaries(
                st.sampled_from(
                    ["rate_hz", "filter", "speed", "noise", "gate", "sound_speed", "x"]
                ),
                config_values,
                max_size=4,
            ),
            "beacons": st.dictionaries(st.text(max_size=4), config_values, max_size=2),
            "site": config_values,
        },
    ),
)


@given(config_docs)
@settings(max_examples=400, deadline=None)
def test_config_loader_raises_only_config_errors_naming_a_key(doc: object) -> None:
    try:
        config_from_dict(doc)
    except ConfigError as exc:
        msg = str(exc)
        assert "\n" not in msg and ": " in msg
