"""Every pair of an artist's paths, together, on real captures (issue #48): the covering array of ``bench/paths.py``.

Each case is a real engine built as ``gstyle stylize`` and the studio's worker build theirs (``engine/build.py``),
on a crop of a real 360° capture or the fern's forward-facing cameras and photos, at short settings (a few steps of
each phase), with the case's controls and run options together; ``check_case`` asserts what each of them must do.
The matrix comes from the controls' table: a control added there is in these cases without a new test.
"""

from __future__ import annotations

import pytest
from bench_cli import load_bench

from gstyle_core.engine.controls import CONTROLS

paths = load_bench("paths")
CASES = paths.covering_cases()
needs_captures = pytest.mark.skipif(paths.captures_missing() is not None,
                                    reason=str(paths.captures_missing()))


def test_the_cases_cover_every_pair_of_values_of_every_control_and_run_option():
    factors = paths.matrix_factors()
    assert {row.name for row in CONTROLS if not row.with_paintings} <= set(factors)
    assert set(paths.RUN_FACTORS) <= set(factors)
    assert paths.missing_pairs(CASES) == []
    assert paths.pair_count() > 1000
    assert len(CASES) < 40  # a covering array, not the product (which is millions of cases)


def test_a_control_row_brings_its_values_by_its_kind():
    by_name = {row.name: row for row in CONTROLS}
    assert paths.control_values(by_name["lambda_edges"]) == ("off", "on")
    assert paths.control_values(by_name["keep_colours"]) == (0.0, 1.0)
    assert paths.control_values(by_name["style_scale"]) == (0.5, 1.0, 2.0)


def test_a_case_outside_the_filter_is_never_drawn():
    assert all(paths.allowed(list(case), list(case.values())) for case in CASES)
    assert not paths.allowed(["tier", "interrupt"], ["preview", "refine"])


@pytest.fixture(scope="module")
def captures(tmp_path_factory):
    return tmp_path_factory.mktemp("captures")


@needs_captures
@pytest.mark.parametrize("number", range(len(CASES)), ids=lambda i: f"case{i}")
def test_every_case_does_what_its_controls_say(number, captures):
    run = paths.run_case(CASES[number], captures)
    paths.check_case(run)
