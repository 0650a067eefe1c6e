"""Fixtures shared by the identify tests."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def discovery_clean(tmp_path_factory: pytest.TempPathFactory):
    """The clean logs of tests/identify/test_discovery.py identified once (result, the lower vehicle's test
    units): the twin without a hidden effect that test_discovery and test_delays compare against."""
    from .test_discovery import _run

    return _run(tmp_path_factory.mktemp("discovery_clean"), None)
