"""The studio's own saves (``gstyle_core/engine/save_pacing.py``): an interval after stepping starts, further apart
when a save costs more than its share of the time."""

import pytest

from gstyle_core.engine.save_pacing import SavePacing


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_nothing_is_due_before_stepping_starts_then_every_interval():
    clock = Clock()
    pacing = SavePacing(30.0, 0.03, clock)
    clock.now += 1000
    assert not pacing.due()
    pacing.start()
    clock.now += 29.9
    assert not pacing.due()
    clock.now += 0.2
    assert pacing.due()
    pacing.saved(0.5)  # cheap: 0.5 s of 30 is under 3 %
    clock.now += 29.9
    assert not pacing.due()
    clock.now += 0.2
    assert pacing.due()


def test_a_costly_save_spaces_the_next_one_to_keep_its_share():
    clock = Clock()
    pacing = SavePacing(30.0, 0.03, clock)
    pacing.start()
    clock.now += 30
    pacing.saved(3.0)  # 3 s at 3 %: the next 100 s later
    clock.now += 99
    assert not pacing.due()
    clock.now += 1.5
    assert pacing.due()
    assert pacing.last_cost == 3.0


@pytest.mark.parametrize("interval, share", [(0, 0.03), (-1, 0.03), (30, 0), (30, 1.5)])
def test_pacing_refuses_nonsense(interval, share):
    with pytest.raises(ValueError):
        SavePacing(interval, share)
