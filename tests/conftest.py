"""Shared fixtures: paths to the shared test data next to the checkout."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("QOGI_SHARED_DIR", REPO.parent / "shared"))


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    if not SHARED.is_dir():
        pytest.fail(f"shared test data not found at {SHARED}; set QOGI_SHARED_DIR")
    return SHARED


@pytest.fixture(scope="session")
def hitran_dir(shared_dir: Path) -> Path:
    return shared_dir / "hitran"
