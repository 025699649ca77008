"""Shared fixtures: the FMUs, built once per test session from the current sources."""

import os
from pathlib import Path

import pytest
from hypothesis import settings

from dfwb.build_fmus import build_all

ROOT = Path(__file__).resolve().parents[1]

# Property tests: 50 random cases each in CI; DFWB_HYPOTHESIS=stress for 1000.
settings.register_profile("default", max_examples=50, deadline=None)
settings.register_profile("stress", max_examples=1000, deadline=None)
settings.load_profile(os.environ.get("DFWB_HYPOTHESIS", "default"))


@pytest.fixture(scope="session")
def fmus():
    """{model name: path} of the three plant FMUs, built into build/fmus if stale."""
    paths = build_all(ROOT / "build" / "fmus", report=lambda message: None)
    return {path.stem: path for path in paths}
