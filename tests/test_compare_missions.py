"""bench.compare_missions: two Monte Carlo runs of the same seeds, paired per class and per
geometry, as BENCHMARKS.md's paired tables are made."""

from __future__ import annotations

import json
from pathlib import Path

from bench.compare_missions import compare, load


def _row(seed: int, kind: str, rms: float, ok99: float | None, diverged: bool) -> dict:
    default = {"rms_m": rms, "inside95": 0.9, "ok_inside99": ok99}
    return {"seed": seed, "class": "base", "kind": kind, "bound_m": 10.0,
            "default": default, "diverged": diverged}  # fmt: skip


def test_each_geometry_gets_its_row_with_ok_and_divergences(tmp_path: Path) -> None:
    before = [_row(1, "beacon", 20.0, 1.0, False), _row(2, "lbl-2", 30.0, 0.90, False),
              _row(3, "lbl-3", 10.0, None, False)]  # fmt: skip
    after = [_row(1, "beacon", 20.0, 1.0, True), _row(2, "lbl-2", 15.0, 1.0, False),
             _row(3, "lbl-3", 10.0, None, False)]  # fmt: skip
    files = []
    for name, rows in (("b", before), ("a", after)):
        f = tmp_path / f"{name}.jsonl"
        f.write_text("".join(json.dumps(r) + "\n" for r in rows), encoding="utf-8")
        files.append(load(str(f)))
    lines = {ln.split(" | ")[0]: ln.split(" | ") for ln in compare(*files) if ln.startswith("| ")}
    two = lines["| 2-transponder"]
    assert two[1:4] == ["1", "3.00", "1.50"]  # RMS over the bound, before and after
    assert two[8:12] == ["0.900", "1.000", "1", "0"]  # ok in99, then false ok, before/after
    assert lines["| 3-transponder"][8:10] == ["-", "-"]  # never ok: no fraction to give
    assert lines["| single beacon"][12:14] == ["0", "1 |"]  # its divergence, after
    assert lines["| all"][1] == "3" and lines["| all"][12:14] == ["0", "1 |"]
