"""The smoother's history on disk gives back exactly what was written, so a day's
``--smooth`` replay smooths as it did in memory."""

from __future__ import annotations

import numpy as np

from navd.filter.common import History, Step
from navd.filter.smoother import rts_backward


def _random_steps(n: int, dim: int, rng: np.random.Generator) -> list[Step]:
    out = []
    for k in range(n):
        A = rng.normal(size=(dim, dim))
        P = A @ A.T + dim * np.eye(dim)
        F = np.eye(dim) + 0.1 * rng.normal(size=(dim, dim))
        x = rng.normal(size=dim)
        out.append(Step(0.1 * k, F, x, P, x, P))
    return out


def _fill(h: History, steps: list[Step], rng: np.random.Generator) -> list[Step]:
    """Add the steps, updating and widening the latest as the filters do."""
    kept = []
    for s in steps:
        h.add(s.t, s.F, s.x_pred, s.P_pred)
        x2 = s.x_pred + rng.normal(size=s.x_pred.size)
        P2 = 0.5 * s.P_pred
        h.correct(x2, P2)
        P3 = P2 + np.eye(len(P2))
        h.widen(P3)
        kept.append(Step(s.t, s.F, s.x_pred, s.P_pred + (P3 - P2), x2, P3))
    return kept


def test_steps_come_back_bit_for_bit_across_blocks() -> None:
    rng = np.random.default_rng(4)
    h = History()
    h.enabled = True
    h.BLOCK = 3  # blocks smaller than the history, read out of order below
    kept = _fill(h, _random_steps(11, 5, rng), rng)
    assert len(h) == 11
    for k in [10, 0, 7, 3, 9, 1, 2, 8, 4, 6, 5]:
        a, b = h[k], kept[k]
        assert a.t == b.t
        for name in ("F", "x_pred", "P_pred", "x_filt", "P_filt"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), (k, name)


def test_smoothing_the_disk_history_equals_smoothing_the_list() -> None:
    rng = np.random.default_rng(5)
    h = History()
    h.enabled = True
    h.BLOCK = 4
    kept = _fill(h, _random_steps(30, 4, rng), rng)

    def diff(a: object, b: object) -> np.ndarray:
        return np.asarray(a) - np.asarray(b)

    def apply(x: object, dx: np.ndarray) -> object:
        return np.asarray(x) + dx

    disk = list(rts_backward(h, diff, apply))
    memory = list(rts_backward(kept, diff, apply))
    assert [k for k, _, _ in disk] == list(range(29, -1, -1))
    for (k1, x1, P1), (k2, x2, P2) in zip(disk, memory, strict=True):
        assert k1 == k2 and np.array_equal(x1, x2) and np.array_equal(P1, P2)


def test_a_disabled_history_keeps_nothing() -> None:
    h = History()
    h.add(0.0, np.eye(2), np.zeros(2), np.eye(2))
    h.correct(np.ones(2), np.eye(2))
    assert len(h) == 0


def test_only_the_kalman_modes_are_smoothable() -> None:
    """vlbl replaces its state at each fix: it carries no step history at all, and a
    navigator asked to keep one for it smooths nothing rather than raising."""
    from navd.filter import Navigator
    from navd.filter.common import Smoothable
    from navd.filter.navparts import make_filter
    from navd.records import Gps
    from navd.settings import config_from_dict

    for mode, smoothable in (("default", True), ("thesis", True), ("vlbl", False)):
        cfg = config_from_dict({"navigation": {"filter": mode}})
        assert isinstance(make_filter(cfg), Smoothable) is smoothable
        nav = Navigator(cfg, keep_history=True)
        out = [o for k in range(20) for o in nav.feed(Gps(k * 0.1, 37.05, -80.66, 0.0, 1))]
        assert out and len(list(nav.smoothed())) == (len(out) if smoothable else 0)
