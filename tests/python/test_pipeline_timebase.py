"""Time is what time_s says: dropped frames and gaps in a synthetic release
(column densities from the truth maps, isolating the velocimetry and flux),
and the run streamed in blocks."""

import numpy as np
import pytest

import qogi
from qogi.io.recording import Recording, Truth
from qogi.pipeline import QuantifyConfig, quantify
from qogi.pipeline.surfaces import Surface
from qogi.pipeline.timebase import frame_timebase, stream_blocks

SURFACE = [Surface([(100.0, 200.0), (220.0, 200.0)])]


@pytest.fixture(scope="module")
def lab(lab_clip):
    return qogi.open_recording(lab_clip(4.0)).load()


def cfg(**kw):
    return QuantifyConfig(species=["CH4"], column_density="truth", source=(159.5, 227.0), **kw)


def subset(rec, keep, time_s):
    """The frames ``keep`` of ``rec`` (and their truth maps) at ``time_s``."""
    ds = {
        k: (np.asarray(v)[keep] if np.shape(v)[:1] == (rec.n_frames,) else np.asarray(v))
        for k, v in rec.truth.datasets.items()
    }
    truth = Truth(dict(rec.truth.emission_rate_kg_s), ds, dict(rec.truth.attrs))
    return Recording.from_arrays(
        rec.to_array()[keep],
        time_s,
        quantity=rec.quantity,
        camera=rec.camera,
        scene=rec.scene,
        truth=truth,
    )


def test_timebase_counts_dropped_frames_and_cuts_at_gaps():
    t = np.array([0, 1, 2, 4, 5, 6, 3606, 3607, 3608, 3609], float) / 10
    tb = frame_timebase(t, 10.0)
    assert tb.dropped == [(2, 1), (5, 3600 - 1)]  # 360 s at 10 Hz
    assert tb.segments == [(0, 6), (6, 10)]
    np.testing.assert_allclose(tb.pair_intervals[:3], [1, 1, 2])
    blocks = stream_blocks([(0, 100)], 30, overlap=4)
    assert [b.keep for b in blocks] == [(0, 25), (25, 50), (50, 75), (75, 100)]
    assert blocks[1].read == (21, 54) and blocks[0].read == (0, 29)


def test_frames_dropped_at_random_read_the_full_rate_with_honest_times(lab):
    full = quantify(lab, SURFACE, cfg()).surfaces[0].species["CH4"]
    rng = np.random.default_rng(7)
    keep = np.sort(rng.choice(lab.n_frames, int(0.6 * lab.n_frames), replace=False))
    honest = quantify(subset(lab, keep, lab.time_s[keep]), SURFACE, cfg())
    r = honest.surfaces[0].species["CH4"]
    assert full.ci90_kg_h[0] <= r.mean_kg_h <= full.ci90_kg_h[1]
    assert r.ci90_kg_h[0] <= full.mean_kg_h <= r.ci90_kg_h[1]
    assert abs(r.mean_kg_h / full.mean_kg_h - 1) < 0.15
    d = [w for w in honest.warnings if w.code == "frames-dropped"]
    assert d and d[0].data["dropped"] == lab.n_frames - len(keep)
    np.testing.assert_allclose(r.time_s, lab.time_s[keep])
    # The same frames taken as consecutive (what a 1/fps clock assumes) read
    # ~+45 %, outside the honest interval: the test can tell.
    naive = (
        quantify(subset(lab, keep, np.arange(len(keep)) / lab.camera.frame_rate_hz), SURFACE, cfg())
        .surfaces[0]
        .species["CH4"]
    )
    assert not r.ci90_kg_h[0] <= naive.mean_kg_h <= r.ci90_kg_h[1]


def test_a_one_hour_gap_is_reported_and_not_paired_across(lab):
    t = lab.time_s.copy()
    t[30:] += 3600.0
    res = quantify(subset(lab, np.arange(lab.n_frames), t), SURFACE, cfg())
    full = quantify(lab, SURFACE, cfg()).surfaces[0].species["CH4"]
    d = next(w for w in res.warnings if w.code == "frames-dropped")
    assert d.data["gaps_s"][0][0] == 29 and d.data["gaps_s"][0][1] == pytest.approx(3600.0, abs=0.1)
    assert "3.6e+03 s" in d.message
    assert res.info["blocks"] == 2
    r = res.surfaces[0].species["CH4"]
    np.testing.assert_allclose(r.time_s, t)
    assert r.ci90_kg_h[0] <= full.mean_kg_h <= r.ci90_kg_h[1]


def test_blocks_read_the_rate_of_one_pass(lab):
    one = quantify(lab, SURFACE, cfg()).surfaces[0].species["CH4"]
    res = quantify(lab, SURFACE, cfg(block_frames=20))
    r = res.surfaces[0].species["CH4"]
    assert res.info["blocks"] == 3
    assert r.n_frames == lab.n_frames and np.isfinite(r.rate_kg_s).all()
    assert one.ci90_kg_h[0] <= r.mean_kg_h <= one.ci90_kg_h[1]


def test_a_block_holds_ten_seconds_or_450_frames_whichever_is_fewer():
    # The memory bound (benchmarks/bench_memory.py, issue 30): 150 frames of
    # 15 Hz 320 x 240 video (was 450), a 100 Hz block 4.5 s as before; every
    # validation release (10 s at 15 Hz, 2 s at 100 Hz) stays one block.
    from types import SimpleNamespace

    from qogi.pipeline import run

    def rec(hz, h=240, w=320):
        return SimpleNamespace(height=h, width=w, camera=SimpleNamespace(frame_rate_hz=hz))

    auto = QuantifyConfig()
    assert run._block_frames(auto, rec(15.0)) == 150
    assert run._block_frames(auto, rec(100.0)) == 450
    assert run._block_frames(auto, rec(15.0, 24, 32)) == run.BLOCK_BYTES // (8 * 4 * 24 * 32)
    assert run._block_frames(QuantifyConfig(block_frames=64), rec(15.0)) == 64


def test_the_temporal_percentiles_and_noise_by_the_engine_are_numpys_own():
    from qogi.pipeline import background_choice as bc

    rng = np.random.default_rng(3)
    for shape in [(41, 2, 90, 70), (5, 1, 3, 4), (2, 1, 4, 4), (200, 1, 7, 9)]:
        for dtype in (np.float32, np.float64):
            st = (rng.standard_normal(shape) * 1e-3).astype(dtype)
            ref = np.percentile(st, (5, 50, 95), axis=0)
            got = bc.temporal_percentiles(st, (5, 50, 95))
            assert got.dtype == ref.dtype and np.array_equal(got, ref)
            d = np.diff(st, axis=0)
            mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0) * 1.4826 / np.sqrt(2.0)
            assert np.array_equal(bc._noise(st), np.median(mad.reshape(shape[1], -1), axis=1))
            # a channel's slice of the stack (strided frames, not copied): the same
            one = st[:, -1]
            assert np.array_equal(
                bc.temporal_percentiles(one, (10, 90)), np.percentile(one, (10, 90), axis=0)
            )
    # a series holding NaN: NaN, as numpy says
    st = rng.standard_normal((9, 1, 2, 2)).astype(np.float32)
    st[3, 0, 1, 1] = np.nan
    got = bc.temporal_percentiles(st, (50,))
    assert np.isnan(got[0, 0, 1, 1]) and np.isfinite(got[0, 0, 0, 0])
