"""The run's minimum-detectable column map (issue 28 item 4): in the Result,
each surface's median in its detection record, the plot, the report and the
command line's --plot."""

from __future__ import annotations

from statistics import NormalDist

import numpy as np
import pytest
from test_interrupt import SURFACE, small_recording

import qogi
from qogi.apps.cli import main
from qogi.physics.forward import forward_model
from qogi.pipeline.detection import CONFIDENCE, DETECTION_SIGMA, noise_equivalent_column


@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    return small_recording(tmp_path_factory.mktemp("mdc") / "small.h5", n_frames=12)


@pytest.fixture(scope="module")
def result(rec):
    cfg = qogi.QuantifyConfig(species=["CH4"], source=(16, 22), num_threads=1)
    return qogi.quantify(qogi.open_recording(rec), [qogi.Surface.parse(SURFACE)], cfg)


def test_the_map_is_k_plus_z_noise_columns_at_each_pixels_own_background(result, rec):
    mdc = result.min_detectable_column("CH4")
    assert result.min_detectable_column_species == ["CH4"]
    assert mdc.shape == (24, 32) and np.all(np.isfinite(mdc))
    # Far from the warm blob the background is 285 + 0.5 x / 32 K: the gas at
    # 288 K has less contrast to the right, so a larger column is needed there.
    r = qogi.open_recording(rec)
    model = forward_model(r.channels, ["CH4"], r.scene.pressure_Pa)
    z = NormalDist().inv_cdf(CONFIDENCE)
    for x in (2, 30):
        t_bg = 285.0 + 0.5 * x / 32
        nec = noise_equivalent_column(model, "CH4", 0.02, t_bg, 288.0, 288.0)
        assert mdc[2, x] == pytest.approx((DETECTION_SIGMA + z) * nec, rel=2e-3)
    assert mdc[2, 30] > 1.05 * mdc[2, 2]
    # The surface's median of the map is in its detection record.
    det = result.surfaces[0].species["CH4"].detection
    along = mdc[10, 4:29]
    assert det["min_detectable_column_kg_m2"] == pytest.approx(np.median(along), rel=0.02)


def test_a_result_without_a_map_says_why(result):
    bare = qogi.Result(
        result.surfaces, config=result.config, recording_path="x.h5", pixel_status={}
    )
    assert bare.min_detectable_column_species == []
    with pytest.raises(ValueError, match="no minimum-detectable column map"):
        bare.min_detectable_column()
    with pytest.raises(ValueError, match="no minimum-detectable column map"):
        bare.plot(kind="detectability")
    with pytest.raises(ValueError, match="no map for 'CO2'"):
        result.min_detectable_column("CO2")


def test_plot_report_and_the_command_lines_plot(result, rec, tmp_path, capsys):
    fig = result.plot(tmp_path / "d.png", kind="detectability")
    assert (tmp_path / "d.png").stat().st_size > 10_000 and fig.axes
    with pytest.raises(ValueError, match="'detectability'"):
        result.plot(kind="nope")
    code = main(
        ["quantify", str(rec), "--surface", SURFACE, "--source", "16,22",
         "--plot", str(tmp_path / "q.png"), "--report", str(tmp_path / "q.pdf"), "-q"]
    )  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert (tmp_path / "q_detectability.png").stat().st_size > 10_000
    assert b"/Count 3" in (tmp_path / "q.pdf").read_bytes()  # page 3: the map
