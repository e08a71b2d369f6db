"""Pipeline mechanics on a synthetic release, isolated from the inversion:
column densities from the recording's truth maps (validation mode). The flux
sum, its sign convention, partial results on cancel and bad input."""

import json
import tracemalloc

import numpy as np
import pytest

import qogi
from qogi.pipeline import Cancelled, QuantifyConfig, quantify
from qogi.pipeline import velocity as velocity_stage
from qogi.pipeline.surfaces import Region, Surface


@pytest.fixture(scope="module")
def lab(lab_clip):
    return qogi.open_recording(lab_clip(2.0))


def truth_cfg(**kw):
    return QuantifyConfig(species=["CH4"], column_density="truth", **kw)


def test_flux_with_a_given_wind_is_column_times_speed_times_length(lab):
    row = 200.0
    s = Surface([(100.0, row), (220.0, row)])
    res = quantify(lab, [s], truth_cfg(velocity="wind", wind_speed_m_s=0.5))
    r = res.surfaces[0].species["CH4"]
    # Independent sum: truth column along the row x 0.5 m/s x pixel length.
    cols = np.asarray(lab.truth.datasets["column_density_kg_m2_CH4"])
    pix = lab.scene.distance_m * lab.camera.ifov_rad
    expect = cols[:, 200, 100:220].sum(axis=1) * 0.5 * pix
    # Samples are at half-pixel offsets along an integer row: a smooth field
    # sums the same to within a fraction of a percent.
    np.testing.assert_allclose(r.rate_kg_s, expect, rtol=0.02)


def test_sign_convention_left_hand_normal_and_source(lab):
    s = Surface([(100.0, 200.0), (220.0, 200.0)], "left-to-right")
    back = s.reversed()
    res = quantify(lab, [s, back], truth_cfg(velocity="wind", wind_speed_m_s=0.5))
    a = res.surfaces[0].species["CH4"].mean_kg_h
    b = res.surfaces[1].species["CH4"].mean_kg_h
    # The "wind" speed is applied along each surface's own normal, so both are
    # positive; the sign convention shows in the velocimetry instead:
    res = quantify(lab, [s, back], truth_cfg(velocity="fluid"))
    up = res.surfaces[0].species["CH4"].mean_kg_h
    down = res.surfaces[1].species["CH4"].mean_kg_h
    assert a > 0 and b > 0
    assert up > 0 > down  # drawn left to right: upward flow counts positive
    assert up == pytest.approx(-down, rel=1e-6)
    # --source orients both ways of drawing the same line alike.
    src = truth_cfg(velocity="fluid", source=(159.5, 227.0))
    one = quantify(lab, [s], src).surfaces[0].species["CH4"].mean_kg_h
    other = quantify(lab, [back], src).surfaces[0].species["CH4"].mean_kg_h
    assert one > 0 and one == pytest.approx(other, rel=1e-9)


def test_a_blocks_velocity_stage_holds_three_stacks_of_the_flows_part_at_most(lab, monkeypatch):
    # The velocity stage gets the block's column field (frames, h, w) float32
    # and adds the flow's normalised part and the two frame-velocity stacks
    # over that part: no banded copy of the field for the transport, no
    # quality and validity, no second pair of velocity stacks (numpy's
    # allocations, traced: before, 6.25 such stacks and one of the field).
    seen = []
    stage = velocity_stage.block_velocity

    def traced(st, cols, blk, say):
        tracemalloc.start()
        try:
            base = tracemalloc.get_traced_memory()[0]
            flows = stage(st, cols, blk, say)
            peak = tracemalloc.get_traced_memory()[1] - base
            seen.append((peak, flows.u.nbytes, cols.fields.nbytes, cols.fields.shape[0]))
        finally:
            tracemalloc.stop()
        return flows

    monkeypatch.setattr(velocity_stage, "block_velocity", traced)
    s = Surface([(100.0, 200.0), (220.0, 200.0)])
    res = quantify(lab, [s], truth_cfg(velocity="fluid", source=(159.5, 227.0)))
    assert res.info["flux_level"].startswith("on")
    ((peak, stack, field, frames),) = seen
    # Scratch beyond the three stacks: the band's line sums take 32 frames of
    # the field at a time, the flow's scale and stride a stack for a moment.
    chunk = field * min(1.0, velocity_stage.BAND_CHUNK_FRAMES / frames)
    assert 2 * stack < peak < 4 * stack + chunk, (peak / stack, chunk / stack)


def test_normal_of_a_left_to_right_line_points_up():
    xy, n, dl = Surface([(0.0, 10.0), (4.0, 10.0)]).samples(1.0)
    np.testing.assert_allclose(n, [[0.0, -1.0]] * 4)
    assert dl.sum() == pytest.approx(4.0)


def test_result_exports(lab, tmp_path):
    s = Surface([(100.0, 190.0), (220.0, 190.0)], "mid")
    res = quantify(lab, [s], truth_cfg(), keep_maps=True)
    d = json.loads(res.to_json(tmp_path / "r.json"))
    sp = d["surfaces"][0]["species"]["CH4"]
    for key in ("mean_kg_h", "ci90_kg_h", "n_frames", "time_s", "rate_kg_h", "truth_kg_h"):
        assert key in sp
    assert d["surfaces"][0]["points"] == [[100.0, 190.0], [220.0, 190.0]]
    assert sp["truth_kg_h"] == pytest.approx(lab.truth.emission_rate_kg_s["CH4"] * 3600)
    res.to_csv(tmp_path / "r.csv")
    lines = (tmp_path / "r.csv").read_text().splitlines()
    assert lines[0] == "surface,species,time_s,rate_kg_h,pixels_used"
    assert len(lines) == 1 + lab.n_frames
    res.plot(tmp_path / "rates.png")
    res.plot(tmp_path / "maps.png", kind="maps")
    assert (tmp_path / "rates.png").stat().st_size > 1000
    assert "kg/h" in res.summary()


def test_cancel_keeps_the_frames_done(lab):
    calls = []

    def progress(fraction, message):
        calls.append(fraction)
        return fraction < 0.3

    with pytest.raises(Cancelled) as e:
        quantify(lab, [Surface([(100.0, 200.0), (220.0, 200.0)])], truth_cfg(), progress=progress)
    part = e.value.partial
    assert part is not None and not part.complete
    n = part.surfaces[0].species["CH4"].n_frames
    assert 0 < n < lab.n_frames


@pytest.mark.parametrize(
    "kwargs, words",
    [
        (dict(species=[]), ["species"]),
        (dict(gas_temperature="hot"), ["gas_temperature"]),
        (dict(gas_temperature=5000.0), ["gas_temperature", "[150, 600]"]),
        (dict(velocity="magic"), ["velocity", "fluid"]),
        (dict(velocity="wind", wind_speed_m_s=0.0), ["wind_speed_m_s", "(0, 100]"]),
        (dict(averaging="sometimes"), ["averaging"]),
        (dict(background="guess"), ["background"]),
        (dict(frames=(5, 2)), ["frames"]),
        (dict(pair_stride=0), ["pair_stride", "[1, 100]"]),
        (dict(pair_stride=2.5), ["pair_stride", "None (automatic)"]),
    ],
)
def test_config_rejects_bad_values(kwargs, words):
    with pytest.raises(ValueError) as e:
        QuantifyConfig(**kwargs)
    for w in words:
        assert w in str(e.value)


def test_bad_surfaces_and_modes_are_clear_errors(lab):
    with pytest.raises(ValueError, match="outside the 320x240 image"):
        quantify(lab, [Surface([(10.0, 10.0), (400.0, 10.0)])], truth_cfg())
    with pytest.raises(ValueError, match="no control surface"):
        quantify(lab, [], truth_cfg())
    with pytest.raises(ValueError, match=">= 2 channels"):
        quantify(
            lab,
            [Surface([(100.0, 200.0), (220.0, 200.0)])],
            QuantifyConfig(gas_temperature="infer"),
        )
    with pytest.raises(ValueError, match="expected an even number"):
        Surface.parse("1,2,3")
    with pytest.raises(ValueError, match="empty"):
        Region(5, 5, 5, 10)
