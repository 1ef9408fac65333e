"""Shared pytest configuration.

Hypothesis profiles for the fuzz tests (``tests/test_fuzz_readers.py``), chosen with ``GSTYLE_FUZZ_PROFILE``:
"ci" (the default: few examples, derandomized so CI runs are repeatable) and "soak" (many random examples,
failures kept in the ``.hypothesis`` database). The fuzz tests apply the profile themselves, so other tests
keep hypothesis' defaults.
"""

from __future__ import annotations

import os
from datetime import timedelta

from hypothesis import HealthCheck, settings

FUZZ_PROFILE = os.environ.get("GSTYLE_FUZZ_PROFILE", "ci")
_SLOW_CHECKS = [HealthCheck.too_slow, HealthCheck.data_too_large]

settings.register_profile("ci", max_examples=12, deadline=timedelta(seconds=5), derandomize=True, database=None,
                          suppress_health_check=_SLOW_CHECKS, print_blob=True)
settings.register_profile("soak", max_examples=1000, deadline=timedelta(seconds=10),
                          suppress_health_check=_SLOW_CHECKS, print_blob=True)
