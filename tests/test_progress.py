"""Progress lines: counts, rate and ETA; reused items kept out of the rate and the ETA."""

from __future__ import annotations

import logging

import pytest

import dexlite_pipeline.progress as progress_module
from dexlite_pipeline.progress import ProgressLog, format_duration


class Clock:
    """A settable ``time.perf_counter``."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def clock(monkeypatch):
    fake = Clock()
    monkeypatch.setattr(progress_module.time, "perf_counter", fake)
    return fake


def test_durations_are_written_as_minutes_or_hours():
    assert format_duration(59.4) == "0:59"
    assert format_duration(3 * 60 + 5) == "3:05"
    assert format_duration(2 * 3600 + 61) == "2:01:01"
    assert format_duration(-4) == "0:00"


def test_rate_and_eta_come_from_the_items_done(clock):
    progress = ProgressLog(logging.getLogger("test"), "lift test", 100, unit="grasps")
    clock.now += 10
    progress.advance(20)
    assert progress.line() == "lift test: 20/100 grasps (20%), 2 grasps/s, elapsed 0:10, ETA 0:40"


def test_reused_items_count_as_done_but_not_in_the_rate_nor_the_eta(clock):
    progress = ProgressLog(logging.getLogger("test"), "preparation", 100, unit="objects", reusable=60)
    clock.now += 1
    progress.advance(50, reused=True)  # a burst of reused assets: no work, no rate
    assert progress.line() == "preparation: 50/100 objects (50%; 50 reused), 0 objects/s, elapsed 0:01"
    clock.now += 9
    progress.advance(5)  # 5 built in 10 s; still to come: 10 reused and 35 to build
    assert progress.line() == "preparation: 55/100 objects (55%; 50 reused), 0.5 objects/s, elapsed 0:10, ETA 1:10"
    progress.advance(10, reused=True)
    assert progress.line().endswith("ETA 1:10")


def test_a_line_is_logged_first_then_at_most_every_interval_and_at_the_end(clock, caplog):
    caplog.set_level(logging.INFO, logger="test")
    progress = ProgressLog(logging.getLogger("test"), "stage", 4, every_s=10)
    progress.advance()
    clock.now += 1
    progress.advance()  # within the interval: no line
    clock.now += 10
    progress.advance()
    progress.advance()  # the last item
    assert [r.getMessage().split(",")[0] for r in caplog.records] == ["stage: 1/4 items (25%)", "stage: 3/4 items (75%)", "stage: 4/4 items (100%)"]
