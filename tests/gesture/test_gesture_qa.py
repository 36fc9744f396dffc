"""The planner on long scores: work proportional to the score, the same plans as before."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import common.gesture.planner as planner
from common.gesture.plan import hermite
from common.gesture.planner import (
    HIHAT_CLOSE_TAIL_FROM,
    HIHAT_CLOSE_TAIL_M,
    PlannerConfig,
    _open_hihat,
    plan_gestures,
)
from common.kit import EventType as E
from common.kit import load_kit
from common.score.events import DrumEvent, Score
from common.score.limbs import distribute

KIT = load_kit()


def _reference_open_hihat(times: np.ndarray, pos: np.ndarray, vel: np.ndarray, opens: list[float],
                          foot_strokes: list[float], cfg: PlannerConfig) -> tuple[np.ndarray, ...]:
    """The former one-window-at-a-time version (re-sorting the whole track per window)."""
    windows: list[list[float]] = []
    for t in sorted(opens):
        if windows and t - 0.08 - 0.1 <= windows[-1][1] + cfg.hihat_close_s:
            windows[-1][1] = t + 0.12
        else:
            windows.append([t - 0.08, t + 0.12])
    strokes = np.array(foot_strokes)
    for w0, w1 in windows:
        a, b = w0 - 0.1, w1 + cfg.hihat_close_s
        if strokes.size and np.any((strokes > a - cfg.foot_cycle) & (strokes < b + cfg.foot_cycle + 0.01)):
            continue
        if a <= times[0] or b >= times[-1]:
            continue
        ends, _ = hermite(times, pos, vel, np.array([a, b]))
        up = np.array([0.0, 0.0, cfg.hihat_open_lift])
        keep = (times < a) | (times > b)
        new_t, new_p, new_v = [a, w0, w1], [ends[0], ends[0] + up, ends[1] + up], [np.zeros(3)] * 3
        if cfg.hihat_open_lift > HIHAT_CLOSE_TAIL_M:  # a high lift joins the fall from HIHAT_CLOSE_TAIL_M
            u = HIHAT_CLOSE_TAIL_FROM
            new_t.append(w1 + u * cfg.hihat_close_s)
            new_p.append(ends[1] + [0.0, 0.0, HIHAT_CLOSE_TAIL_M * (1.0 - 3.0 * u**2 + 2.0 * u**3)])
            new_v.append(np.array([0.0, 0.0, -HIHAT_CLOSE_TAIL_M * 6.0 * u * (1.0 - u) / cfg.hihat_close_s]))
        times = np.concatenate([times[keep], np.array([*new_t, b])])
        pos = np.concatenate([pos[keep], np.array([*new_p, ends[1]])])
        vel = np.concatenate([vel[keep], np.array([*new_v, np.zeros(3)])])
        order = np.argsort(times, kind="stable")
        times, pos, vel = times[order], pos[order], vel[order]
    return times, pos, vel


def test_open_hihat_splice_gives_the_former_knots_exactly() -> None:
    rng = np.random.default_rng(5)
    cfg = PlannerConfig()
    for _ in range(300):
        span = float(rng.uniform(0.5, 20))
        times = np.unique(rng.uniform(-1, span, int(rng.integers(2, 60))))
        if len(times) < 2:
            continue
        pos, vel = rng.normal(size=(len(times), 3)), rng.normal(size=(len(times), 3))
        opens = list(rng.uniform(-1.5, span + 0.5, int(rng.integers(0, 15))))
        strokes = list(rng.uniform(-1, span, int(rng.integers(0, 4))))
        for got, want in zip(_open_hihat(times, pos, vel, opens, strokes, cfg),
                             _reference_open_hihat(times, pos, vel, opens, strokes, cfg), strict=True):
            assert np.array_equal(got, want)


def _long_score(bars: int) -> Score:
    events = []
    for i in range(bars):  # 120 bpm, an open hi-hat on every bar's last eighth
        t = 2.0 * i
        events += [DrumEvent(t, E.BASS, 0.8), DrumEvent(t + 1.0, E.SNARE, 0.8), DrumEvent(t + 1.75, E.HIHATOPEN, 0.7)]
    return Score(events=events, beats=np.arange(0.0, 2.0 * bars + 1, 0.5))


def test_long_scores_plan_in_work_proportional_to_their_length(monkeypatch: pytest.MonkeyPatch) -> None:
    # each open hi-hat re-sorted the hi-hat foot's whole track, and each beat's nod swept the whole head track:
    # 200,000 notes took six minutes and a day's beats ran out of memory
    score = _long_score(150)
    seen = {"hermite": 0, "exp": 0}

    def counting_hermite(times: np.ndarray, *args: Any) -> tuple[np.ndarray, np.ndarray]:
        seen["hermite"] = max(seen["hermite"], len(times))
        return hermite(times, *args)

    class CountingNumpy:
        def __getattr__(self, name: str) -> Any:
            return getattr(np, name)

        def exp(self, x: np.ndarray) -> np.ndarray:
            seen["exp"] += np.size(x)
            return np.exp(x)

    monkeypatch.setattr(planner, "hermite", counting_hermite)
    monkeypatch.setattr(planner, "np", CountingNumpy())
    plan = plan_gestures(distribute(score, KIT), KIT, score)
    monkeypatch.undo()
    assert len(plan.strokes) == len(score.events)
    assert seen["hermite"] < 200  # the knots around one window, not the whole track
    head_samples = len(plan.head.times)
    assert seen["exp"] < 0.5 * head_samples * len(score.beats) / 10  # a bump's reach per beat, not the track


def test_head_nod_is_unchanged() -> None:
    score = _long_score(6)
    plan = plan_gestures(distribute(score, KIT), KIT, score)
    cfg = PlannerConfig()
    t = plan.head.times
    nod = np.zeros_like(t)
    for b in score.beats:
        if plan.start_time - 1 <= b <= plan.end_time + 1:
            nod += cfg.nod_amplitude * np.exp(-(((t - b) / cfg.nod_width) ** 2))
    assert np.array_equal(plan.head.nod, nod)
