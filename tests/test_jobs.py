"""Many missions at once: on local worker processes or on a Dask cluster on loopback,
the same outputs as one after another."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import mission

from navd.analysis.jobs import run_all
from navd.cli import main
from navd.hil.sim_cli import write_mission


def _missions(tmp_path: Path) -> list[str]:
    logs = []
    for name, seed in (("claytor-1", 1), ("claytor-2", 2), ("claytor-1", 3)):
        d = tmp_path / f"{name}-{seed}"
        write_mission(mission(name, seed), d)
        logs.append(str(d / "measurements.jsonl"))
    return logs


def _outputs(out: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(out.iterdir())}


def test_each_log_alone_and_on_workers_gives_the_same_files(tmp_path: Path, capsys) -> None:
    logs = _missions(tmp_path)
    cfg = str(Path(logs[0]).parent / "config.yaml")
    assert main(["replay", "--each", *logs, "--config", cfg, "--out", str(tmp_path / "j1"),
                 "--jobs", "1"]) == 0
    assert main(["replay", "--each", *logs, "--config", cfg, "--out", str(tmp_path / "j2"),
                 "--jobs", "2"]) == 0
    one, two = _outputs(tmp_path / "j1"), _outputs(tmp_path / "j2")
    assert len(one) == 3 and one == two
    # and each is what a replay of that log alone writes
    assert main(["replay", logs[1], "--config", cfg, "--out", str(tmp_path / "alone.jsonl")]) == 0
    alone = (tmp_path / "alone.jsonl").read_bytes()
    assert one["claytor-2-2-measurements.out.jsonl"] == alone
    said = capsys.readouterr().err
    assert said.count("replayed ") == 7


def test_each_refuses_two_logs_that_would_write_one_file(tmp_path: Path, capsys) -> None:
    for d in ("x/m", "y/m"):
        (tmp_path / d).mkdir(parents=True)
        (tmp_path / d / "log.jsonl").write_text("")
    logs = [str(tmp_path / "x/m/log.jsonl"), str(tmp_path / "y/m/log.jsonl")]
    assert main(["replay", "--each", *logs, "--out", str(tmp_path / "o")]) == 2
    assert "would both write m-log.out.jsonl" in capsys.readouterr().err


def test_one_bad_log_among_many_is_named_and_the_rest_replayed(tmp_path: Path, capsys) -> None:
    logs = _missions(tmp_path)[:1] + [str(tmp_path / "missing.jsonl")]
    assert main(["replay", "--each", *logs, "--out", str(tmp_path / "o"), "--jobs", "2"]) == 1
    err = capsys.readouterr().err
    assert "missing.jsonl" in err and "replayed " in err
    assert (tmp_path / "o" / "measurements.out.jsonl").stat().st_size > 0


def test_jobs_flags_without_each_are_refused(tmp_path: Path, capsys) -> None:
    assert main(["replay", "a.jsonl", "--out", str(tmp_path / "o.jsonl"), "--jobs", "2"]) == 2
    assert "add --each" in capsys.readouterr().err


def test_results_keep_their_order_whatever_the_workers() -> None:
    xs = list(range(40))
    assert run_all(pow, xs, [3] * 40, jobs=1) == run_all(pow, xs, [3] * 40, jobs=2)
    assert run_all(pow, [], [], jobs=2) == []


def test_a_dask_cluster_on_loopback_replays_the_same(tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    logs = _missions(tmp_path)
    cfg = str(Path(logs[0]).parent / "config.yaml")
    assert main(["replay", "--each", *logs, "--config", cfg, "--out", str(tmp_path / "j1"),
                 "--jobs", "1"]) == 0
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address=None,
    ) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        assert main(["replay", "--each", *logs, "--config", cfg, "--out",
                     str(tmp_path / "dask"), "--scheduler", cluster.scheduler_address]) == 0
        assert "replay_one" in cluster.scheduler.task_prefixes  # the cluster ran them
    assert _outputs(tmp_path / "dask") == _outputs(tmp_path / "j1")
