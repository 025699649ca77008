"""Shared fixtures: the FMUs, built once per test session from the current sources."""

from pathlib import Path

import pytest

from dfwb.build_fmus import build_all

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def fmus():
    """{model name: path} of the three plant FMUs, built into build/fmus if stale."""
    paths = build_all(ROOT / "build" / "fmus", report=lambda message: None)
    return {path.stem: path for path in paths}
