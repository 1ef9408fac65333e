"""The width ``gstyle stylize`` measures its quality figures at: 256 px unless ``$GSTYLE_FIGURES_WIDTH`` names another
(the suite sets 64 in tests/conftest.py: its runs are 32 px wide), 64 px in a smoke run."""

from __future__ import annotations

import pytest

from gstyle_core.engine.build import EVALUATION_WIDTH, FIGURES_WIDTH_ENV, SMOKE_ENV, evaluation_width


@pytest.mark.parametrize(("figures", "smoke", "expected"), [
    (None, None, EVALUATION_WIDTH), (None, "1", 64), ("128", None, 128), ("128", "1", 128),
    ("8", None, EVALUATION_WIDTH), ("wide", None, EVALUATION_WIDTH), ("", "0", EVALUATION_WIDTH),
])
def test_the_figures_width_follows_the_environment(monkeypatch, figures, smoke, expected):
    for name, value in ((FIGURES_WIDTH_ENV, figures), (SMOKE_ENV, smoke)):
        if value is None:
            monkeypatch.delenv(name, raising=False)
        else:
            monkeypatch.setenv(name, value)
    assert evaluation_width() == expected
