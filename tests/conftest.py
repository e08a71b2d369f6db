"""Shared fixtures: the line lists the package ships, the third-party sample
files that tests use only when they are present beside the checkout, and the
synthetic lab release that several pipeline tests quantify."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
# Third-party camera files (FLIR samples) are not redistributed with qogi: tests
# that need them look beside the checkout (or in $QOGI_SHARED_DIR) and are
# skipped, saying so, when they are absent.
SHARED = Path(os.environ.get("QOGI_SHARED_DIR", REPO.parent / "shared"))


def pytest_collection_modifyitems(items) -> None:
    """Mark every test that needs the third-party samples ``shared_data``, so
    that CI, whose bare clone has nothing beside it, can run just these in the
    checkout that has them (``pytest -m shared_data``)."""
    for item in items:
        if "shared_dir" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.shared_data)


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    if not (SHARED / "samples").is_dir():
        pytest.skip(
            f"third-party sample files not found at {SHARED / 'samples'} (they are "
            "not shipped with qogi; set QOGI_SHARED_DIR to a folder holding "
            "samples/flir to run this test)"
        )
    return SHARED


@pytest.fixture(scope="session")
def hitran_dir() -> Path:
    """The HITRAN subsets shipped inside the package (python/qogi/data/hitran)."""
    from qogi.physics.spectra import bundled_hitran_dir

    return bundled_hitran_dir()


@pytest.fixture(scope="session")
def lab_clip(tmp_path_factory):
    """The lab CH4 release (preset lab-ch4-5slpm-gf320, seed 4, with truth
    maps) as a file, rendered once per session for each length asked:
    ``lab_clip(duration_s) -> Path``."""
    from qogi.synth import render  # on first use: most sessions render nothing

    paths = {}

    def clip(duration_s: float) -> Path:
        if duration_s not in paths:
            path = tmp_path_factory.mktemp("lab") / "lab.h5"
            render.synthesize(
                "lab-ch4-5slpm-gf320", path, duration_s=duration_s, seed=4, truth_maps=True
            )
            paths[duration_s] = path
        return paths[duration_s]

    return clip
