"""Results that cannot be trusted say so (issue 16): too few frames,
non-physical radiance, a source outside the image or on a surface, a
sub-pixel surface, NaN results. Each example of the issue, reproduced."""

import numpy as np
import pytest

import qogi
from qogi.errors import DataError, UsageError
from qogi.io.recording import Recording
from qogi.pipeline import QuantifyConfig, quantify
from qogi.pipeline.surfaces import Surface

SURFACE = [Surface([(100.0, 200.0), (220.0, 200.0)])]


@pytest.fixture(scope="module")
def lab(lab_clip):
    return qogi.open_recording(lab_clip(2.0)).load()


def cfg(**kw):
    kw.setdefault("column_density", "truth")
    return QuantifyConfig(species=["CH4"], **kw)


def with_frames(rec, frames):
    return Recording.from_arrays(
        frames,
        rec.time_s,
        quantity=rec.quantity,
        camera=rec.camera,
        scene=rec.scene,
        truth=rec.truth,
    )


@pytest.mark.parametrize("n", [2, 3, 4])
def test_two_to_four_frames_are_refused_for_velocimetry(lab, n):
    with pytest.raises(DataError, match="at least 5"):
        quantify(lab, SURFACE, cfg(frames=(0, n), source=(159.5, 227.0)))


def test_few_frames_warn_and_widen_the_interval_to_the_rate_itself(lab):
    res = quantify(lab, SURFACE, cfg(frames=(0, 8), source=(159.5, 227.0)))
    w = [d for d in res.warnings if d.code == "few-frames"]
    assert w and w[0].data["minimum"] == 30 and "30" in w[0].message
    r = res.surfaces[0].species["CH4"]
    # The velocity term alone is the whole rate: the interval spans zero.
    assert r.uncertainty_terms_kg_h["velocity"] == pytest.approx(abs(r.mean_kg_h))
    assert r.ci90_kg_h[0] < 0 < r.ci90_kg_h[1]
    # Given speeds need one frame.
    one = quantify(lab, SURFACE, cfg(frames=(0, 1), velocity="wind", wind_speed_m_s=1.0))
    assert not one.warnings.has("few-frames")


@pytest.mark.parametrize("value", [0.0, -1.0])
def test_a_blank_or_negative_frame_is_refused_not_printed_as_nan(lab, value):
    frames = lab.to_array().copy()
    frames[0] = value
    with pytest.raises(DataError, match="frame 0, channel 0: no pixel has a physical"):
        quantify(with_frames(lab, frames), SURFACE, cfg(source=(159.5, 227.0)))


def test_some_nonphysical_pixels_warn(lab):
    frames = lab.to_array().copy()
    frames[:, :, 10:12, 10:13] = 0.0  # a dead 2x3 patch in every frame
    res = quantify(
        with_frames(lab, frames),
        SURFACE,
        cfg(column_density="inversion", source=(159.5, 227.0), velocity="wind", wind_speed_m_s=1.0),
    )
    w = [d for d in res.warnings if d.code == "radiance-nonphysical"]
    assert w and w[0].data["pixels"] == 6 * lab.n_frames * lab.n_channels
    assert res.complete


def test_source_outside_the_image_warns_and_nan_source_is_a_usage_error(lab):
    res = quantify(lab, SURFACE, cfg(source=(5000.0, 5000.0)))
    assert res.warnings.has("source-outside-image")
    with pytest.raises(UsageError, match="finite"):
        cfg(source=(float("nan"), float("nan")))


def test_source_on_the_surface_warns(lab):
    res = quantify(lab, SURFACE, cfg(source=(159.5, 200.3)))
    w = [d for d in res.warnings if d.code == "source-on-surface"]
    assert w and w[0].surface == "S1" and w[0].data["distance_px"] == pytest.approx(0.3)
    far = quantify(lab, SURFACE, cfg(source=(159.5, 227.0)))
    assert not far.warnings.has("source-on-surface")


def test_a_surface_shorter_than_a_pixel_is_refused(lab):
    with pytest.raises(UsageError, match="at least 1 px"):
        quantify(lab, [Surface([(150.0, 200.0), (150.5, 200.0)])], cfg())


def test_a_nan_result_is_flagged_and_incomplete(lab):
    # A surface where the truth holds no gas and the flow no velocity:
    # columns zero; a wind speed of zero is refused, so make the columns NaN
    # instead, through a recording whose truth maps are NaN on that row.
    ds = {k: np.array(v) for k, v in lab.truth.datasets.items()}
    ds["column_density_kg_m2_CH4"][:, 150, :] = np.nan
    truth = qogi.io.recording.Truth(dict(lab.truth.emission_rate_kg_s), ds, dict(lab.truth.attrs))
    rec = Recording.from_arrays(
        lab.to_array(),
        lab.time_s,
        quantity=lab.quantity,
        camera=lab.camera,
        scene=lab.scene,
        truth=truth,
    )
    res = quantify(
        rec, [Surface([(100.0, 150.0), (220.0, 150.0)])], cfg(velocity="wind", wind_speed_m_s=1.0)
    )
    assert res.warnings.has("nan-in-result") and not res.complete
    assert '"complete": false' in res.to_json()


def test_a_sub_pixel_surface_shift_away_from_the_source_barely_changes_the_rate(lab):
    # The issue saw 50-100 % or a sign flip from a 0.3-px shift; on the lab
    # release the sign flip is the source-on-surface case (the orientation
    # away from a source lying on the line is undefined: warned above); a
    # surface clear of the source reads the same to within a few per cent.
    src = cfg(source=(159.5, 227.0))
    a, b = (
        quantify(lab, [Surface([(100.0, y), (220.0, y)])], src).surfaces[0].species["CH4"].mean_kg_h
        for y in (199.8, 200.1)
    )
    assert a > 0 and abs(b / a - 1) < 0.03
