"""The viewer's view-model without a screen: open, play, draw, configure, run,
cancel, export, and every error path as a readable message."""

from __future__ import annotations

import json
import threading

import h5py
import numpy as np
import pytest
from conftest import (
    AMBIENT_K,
    RATE_HZ,
    H,
    T,
    W,
    channels,
    make_recording,
    temperature_field,
)

import qogi
from qogi_gui import display, results
from qogi_gui.store import UserStore
from qogi_gui.surfaces import RegionDraft, flow_arrow, left_normal
from qogi_gui.viewmodel import ViewModel


@pytest.fixture
def opened(vm, rec_path):
    assert vm.open(rec_path), vm.last_message
    return vm


def errors(vm):
    return [m.text for m in vm.messages if m.level == "error"]


def run_to_end(vm, timeout=10.0):
    assert vm.job.wait(timeout)
    assert vm.poll()


# ---------------------------------------------------------------------- open


def test_open_shows_metadata_and_remembers_the_file(opened, rec_path, store):
    rows = dict(opened.metadata_rows())
    assert rows["camera"] == "test camera"
    assert rows["frames"] == f"{T} x 2 channel(s) x {W}x{H} px"
    assert rows["frame rate"] == f"{RATE_HZ:g} Hz"
    assert rows["distance"] == "3 m"
    assert "3.2-3.4 um" in rows["channel 0"]
    assert rows["true CH4 rate"] == "3.6 kg/h"
    # The recent list is persisted per user: a fresh store on the same folder sees it.
    assert UserStore(store.folder).recent == [str(rec_path)]
    # The form starts from the recording's scene.
    assert opened.settings.species == {"CH4": True, "CO2": False}
    assert opened.settings.distance_m == "3"
    assert opened.settings.frame_stop == str(T)


def test_recent_list_is_most_recent_first_without_duplicates(tmp_path, store):
    paths = [tmp_path / f"r{i}.h5" for i in range(3)]
    for p in paths + [paths[0]]:
        store.add_recent(p)
    assert UserStore(store.folder).recent == [str(paths[0]), str(paths[2]), str(paths[1])]


def test_corrupt_settings_file_is_a_warning_not_a_crash(tmp_path, api):
    folder = tmp_path / "cfg"
    folder.mkdir()
    (folder / "viewer.json").write_text("{not json")
    v = ViewModel(api=api, store=UserStore(folder), demo_provider=lambda p: "")
    assert v.last_message.level == "warning" and "viewer.json" in v.last_message.text
    assert v.store.recent == []


def test_open_missing_file_says_so_and_forgets_it(vm, tmp_path, store):
    missing = tmp_path / "gone.h5"
    store.add_recent(missing)
    assert not vm.open(missing)
    assert "does not exist" in errors(vm)[-1] and str(missing) in errors(vm)[-1]
    assert str(missing) not in store.recent
    assert vm.recording is None


def test_open_non_hdf5_file(vm, tmp_path):
    p = tmp_path / "notes.h5"
    p.write_text("hello")
    assert not vm.open(p)
    assert "is not an HDF5 file" in errors(vm)[-1]


def test_open_file_breaking_the_contract_names_the_attribute(vm, rec_path):
    with h5py.File(rec_path, "a") as f:
        f["scene"].attrs["ambient_temperature_K"] = 20.0
    assert not vm.open(rec_path)
    assert "ambient_temperature_K" in errors(vm)[-1] and "[180, 350]" in errors(vm)[-1]


def test_open_file_with_nan_pixels_marks_them_invalid(vm, tmp_path):
    p = tmp_path / "nan.h5"
    make_recording(nan=True).save(p)
    assert vm.open(p)
    assert any(m.level == "warning" and "1 non-finite" in m.text for m in vm.messages)
    vm.seek(3)
    vm.set_display(channel=0)
    rgba = vm.render()
    assert rgba[5, 7, 3] == 0.0 and rgba[5, 8, 3] == 1.0  # invalid pixel transparent


def test_open_empty_path(vm):
    assert not vm.open("  ")
    assert "no file chosen" in errors(vm)[-1]


# ---------------------------------------------------------------------- display


def test_temperature_display_recovers_the_blackbody_temperatures(opened):
    # Frames hold band radiance of blackbodies at known temperatures: shown as
    # radiometric temperature they must come back (exact truth, independent
    # of the display code's interpolation tables).
    truth = temperature_field()
    for k in range(2):
        assert opened.set_display(channel=k, quantity="radiometric_temperature")
        for f in (0, 5):
            opened.seek(f)
            np.testing.assert_allclose(opened.channel_image(), truth[f], atol=2e-3)


def test_radiance_display_is_the_stored_band_radiance(opened):
    opened.seek(2)
    opened.set_display(channel=1, quantity="radiance")
    ch = channels()[1]
    expect = ch.band_radiance(temperature_field()[2].ravel()).reshape(H, W)
    np.testing.assert_allclose(opened.channel_image(), expect, rtol=1e-6)


def test_colour_mapping_ends_and_fixed_range(opened):
    lut = display.colormap_lut("gray")
    opened.set_display(
        colormap="gray",
        range_mode="fixed",
        quantity="radiometric_temperature",
        fixed_min=290.0,
        fixed_max=300.0,
    )
    rgba = opened.render()
    img = opened.channel_image()
    np.testing.assert_array_equal(
        rgba[img <= 290.0], np.broadcast_to(lut[0], rgba[img <= 290].shape)
    )
    np.testing.assert_array_equal(
        rgba[img >= 300.0], np.broadcast_to(lut[-1], rgba[img >= 300].shape)
    )
    mid = (img > 294.0) & (img < 296.0)
    assert mid.any()
    assert np.all(np.abs(rgba[mid, 0] - (img[mid] - 290.0) / 10.0) < 2.0 / 255 + 1e-6)
    assert opened.last_range == (290.0, 300.0)


def test_auto_ranges(opened):
    opened.set_display(quantity="radiometric_temperature", range_mode="recording")
    lo, hi = opened.display_range()
    truth = temperature_field()
    assert truth.min() - 0.01 <= lo < hi <= truth.max() + 0.01
    opened.set_display(range_mode="frame")
    flo, fhi = opened.display_range()
    f0 = truth[0]
    assert np.percentile(f0, 0.5) - 0.5 < flo and fhi < f0.max() + 0.01


def test_display_errors_are_messages(opened):
    assert not opened.set_display(fixed_min=5.0, fixed_max=1.0)
    assert "min < max" in errors(opened)[-1]
    assert not opened.set_display(channel=7)
    assert "channel must be 0..1" in errors(opened)[-1]
    assert not opened.set_display(colormap="rainbow-unicorn")
    assert not opened.set_display(quantity="counts")


def test_switching_quantity_resets_a_fixed_range_in_the_new_units(opened):
    opened.set_display(quantity="radiance", range_mode="fixed")
    assert opened.display.fixed_max < 10  # W/(m2 sr)
    opened.set_display(quantity="radiometric_temperature")
    assert 280 < opened.display.fixed_min < opened.display.fixed_max < 320  # K


# ---------------------------------------------------------------------- playback


def test_playback_follows_the_recording_times_and_loops(opened):
    clock = opened.clock
    opened.play(True)
    clock.t += 0.25  # 10 Hz: 2.5 frame intervals
    assert opened.tick() and opened.frame == 2
    opened.set_speed(2.0)
    clock.t += 0.2  # 0.4 s of recording at 2x
    opened.tick()
    assert opened.frame == 6
    clock.t += 0.15  # 0.95 s: past the end of 8 frames (0.8 s): loops
    opened.tick()
    assert opened.frame == 1
    opened.play(False)
    clock.t += 1.0
    assert not opened.tick() and opened.frame == 1


def test_seek_step_and_speed_errors(opened):
    opened.seek(99)
    assert opened.frame == T - 1
    opened.seek(-3)
    assert opened.frame == 0
    opened.step(2)
    assert opened.frame == 2
    assert not opened.set_speed(0)
    assert not opened.set_speed("fast")


def test_pixel_readout(opened):
    opened.seek(4)
    r = opened.readout(10.49, 3.51)  # nearest pixel centre: (10, 4)
    assert (r["x"], r["y"]) == (10, 4)
    t = temperature_field()[4, 4, 10]
    for k, ch in enumerate(channels()):
        assert r["channels"][k]["temperature_K"] == pytest.approx(t, abs=2e-3)
        assert r["channels"][k]["radiance"] == pytest.approx(ch.band_radiance(t), rel=1e-6)
    assert opened.readout(-0.6, 3) is None and opened.readout(W - 0.4, 3) is None


# ---------------------------------------------------------------------- drawing


def test_left_hand_normal_convention():
    # docs/pipeline_api.md: a horizontal line drawn left to right counts upward
    # flow (towards smaller y) as positive.
    assert left_normal((0, 10), (5, 10)) == (0.0, -1.0)
    assert left_normal((5, 10), (0, 10)) == (0.0, 1.0)
    # Walking down the image (y increasing) the left hand points to +x.
    assert left_normal((3, 0), (3, 4)) == (1.0, 0.0)
    (mx, my), (hx, hy) = flow_arrow([(0, 10), (10, 10), (10, 0)], 2.0)
    assert (mx, my) == (10.0, 10.0) and (hx, hy) == (10.0, 8.0)


def test_draw_a_line_keeps_the_click_order(opened):
    opened.set_mode("line")
    assert opened.click(4.0, 12.0)
    assert opened.drawing is not None and len(opened.surfaces) == 0
    assert opened.click(28.0, 12.0)
    assert opened.drawing is None
    [s] = opened.surfaces
    assert s.name == "S1" and s.points == [(4.0, 12.0), (28.0, 12.0)]
    tail, head = flow_arrow(s.points, 3.0)
    assert head[1] < tail[1]  # upward flow positive for a left-to-right line


def test_draw_polyline_and_finish_with_right_click(opened):
    opened.set_mode("polyline")
    for p in [(2, 20), (10, 15), (20, 15)]:
        assert opened.click(*p)
    assert opened.click(0, 0, button="right")
    assert opened.surfaces[0].points == [(2, 20), (10, 15), (20, 15)]
    opened.click(5, 5)
    opened.undo_point()
    assert opened.drawing is None
    opened.click(5, 5)
    assert opened.set_mode("view")  # a one-point surface is dropped on leaving
    assert len(opened.surfaces) == 1


def test_drawing_errors(vm, opened):
    opened.set_mode("line")
    assert not opened.click(W + 3.0, 4.0)
    assert "outside the image" in errors(opened)[-1]
    # Inside the edge pixels' squares: kept at the outermost pixel centres.
    assert opened.click(-0.4, H - 0.6)
    assert opened.drawing.points == [(0.0, H - 1.0)]
    opened.cancel_drawing()
    opened.click(3, 3)
    assert not opened.click(3, 3)
    assert "repeats the previous" in errors(opened)[-1]
    opened.set_mode("polyline")
    opened.click(3, 3)
    assert not opened.finish_drawing()
    assert "at least two distinct points" in errors(opened)[-1]


def test_click_before_opening_is_a_message(vm):
    assert not vm.click(1, 1)
    assert "open a recording" in errors(vm)[-1]


def test_edit_delete_reverse_rename(opened):
    assert opened.add_surface([(2, 5), (20, 5)], name="low")
    assert opened.add_surface([(2, 2), (20, 2)])
    assert opened.surfaces[1].name == "S2"
    assert opened.move_vertex(0, 1, 100.0, -9.0)  # dragged off the image: kept at its edge
    assert opened.surfaces[0].points[1] == (W - 1.0, 0.0)
    assert not opened.move_vertex(0, 0, W - 1.0, 0.0)  # onto the other point
    assert opened.reverse_surface(1)
    assert opened.surfaces[1].points == [(20, 2), (2, 2)]
    tail, head = flow_arrow(opened.surfaces[1].points, 2.0)
    assert head[1] > tail[1]  # reversed: downward flow counts positive
    assert not opened.rename_surface(1, "low")
    assert "exists already" in errors(opened)[-1]
    assert opened.rename_surface(1, "high")
    opened.set_mode("edit")
    assert opened.click(10.0, 1.9) and opened.selected == 1
    assert opened.delete_surface(0)
    assert [s.name for s in opened.surfaces] == ["high"]
    assert not opened.delete_surface(5)
    assert not opened.add_surface([(1, 1), (1, 1)])
    assert not opened.add_surface([(1, 1), (500, 1)])


def test_background_region_from_two_corners(opened):
    opened.set_mode("region")
    assert opened.click(2.6, 3.2)
    assert opened.region_corner == (2.6, 3.2)
    assert opened.click(6.4, 1.0)
    # pixel centres inside x in [2.6, 6.4], y in [1.0, 3.2]: x 3..6, y 1..3
    assert opened.region.as_tuple() == (3, 1, 7, 4)
    assert opened.settings.background == "region"
    assert RegionDraft.from_corners((-3, -3), (100, 100), W, H).as_tuple() == (0, 0, W, H)
    opened.set_region(None)  # back to qogi.QuantifyConfig's default
    assert opened.settings.background == qogi.QuantifyConfig().background


def test_pick_source(opened):
    opened.set_mode("source")
    assert opened.click(16.0, 22.0)
    assert opened.settings.use_source
    assert (opened.settings.source_x, opened.settings.source_y) == ("16.0", "22.0")


# ---------------------------------------------------------------------- settings


def test_each_field_reports_its_own_problem(opened):
    bad = opened.update_settings(
        species={"CH4": False, "CO2": False},
        gas_temperature_mode="given",
        gas_temperature_K="abc",
        velocity="wind",
        wind_speed_m_s="0",
        background="percentile",
        background_percentile="100",
        distance_m="-2",
        ambient_temperature_K="400",
        pressure_Pa="1e6",
        sigma_m="0",
        frame_start="7",
        frame_stop="",
        num_threads="-1",
        use_source=True,
        source_x="5",
        source_y="99",
    )
    assert "tick at least one" in bad["species"]
    assert "a temperature in K; got 'abc'" in bad["gas_temperature_K"]
    assert bad["wind_speed_m_s"] == "must be within (0, 100] m/s; got 0"
    assert "[0, 50]" in bad["background_percentile"]
    assert bad["distance_m"] == "must be within [0.001, 100000] m; got -2"
    assert "[180, 350] K" in bad["ambient_temperature_K"]
    assert "Pa" in bad["pressure_Pa"]
    assert bad["sigma_m"] == "must be within [0.0001, 10] m; got 0"
    assert "fewer than 2" in bad["frame_stop"]
    assert ">= 0" in bad["num_threads"]
    assert "outside the image" in bad["source"]
    assert bad["averaging"] == "" and bad["velocity"] == ""


def test_infer_needs_two_channels_and_region_needs_picking(vm, tmp_path):
    p = tmp_path / "one.h5"
    make_recording(n_channels=1).save(p)
    vm.open(p)
    bad = vm.update_settings(gas_temperature_mode="infer", background="region")
    assert "needs >= 2 channels" in bad["gas_temperature_K"]
    assert "pick the region" in bad["background"]


def test_valid_form_builds_the_contract_config(opened):
    opened.set_mode("region")
    opened.click(0, 0)
    opened.click(5, 5)
    ok = opened.update_settings(
        species={"CH4": True, "CO2": True},
        gas_temperature_mode="given",
        gas_temperature_K="310",
        velocity="exit",
        exit_velocity_m_s="0.3",
        averaging="time-averaged",
        sigma_m="0.05",
        frame_start="1",
        frame_stop="7",
        num_threads="1",
    )
    assert not any(ok.values()), ok
    cfg = opened.settings.build_config(qogi, opened.recording, opened.region)
    assert cfg.species == ["CH4", "CO2"] and cfg.gas_temperature == 310.0
    assert cfg.velocity == "exit" and cfg.exit_velocity_m_s == 0.3
    assert cfg.averaging == "time-averaged" and cfg.sigma_m == 0.05
    assert cfg.background == qogi.Region(0, 0, 6, 6)
    assert cfg.frames == (1, 7) and cfg.num_threads == 1
    assert cfg.distance_m == 3.0 and cfg.ambient_temperature_K == AMBIENT_K


# ---------------------------------------------------------------------- run


def test_run_passes_the_drawn_surfaces_and_shows_the_result(opened, api):
    opened.add_surface([(4, 12), (28, 12)], name="A")
    opened.add_surface([(4, 6), (16, 4), (28, 6)], name="B")
    assert opened.start_run()
    run_to_end(opened)
    [(surfs, cfg, keep)] = api.calls
    assert [(s.name, s.points) for s in surfs] == [
        ("A", [(4.0, 12.0), (28.0, 12.0)]),
        ("B", [(4.0, 6.0), (16.0, 4.0), (28.0, 6.0)]),
    ]
    assert cfg.species == ["CH4"] and cfg.velocity == "fluid" and keep is True
    rows = results.rate_rows(opened.result)
    assert [(r.surface, r.species) for r in rows] == [("A", "CH4"), ("B", "CH4")]
    assert rows[0].truth_kg_h == pytest.approx(3.6)
    rate = opened.result.surfaces[0].species["CH4"].rate_kg_s
    assert rows[0].n_frames_valid == np.count_nonzero(np.isfinite(rate)) > 0
    assert opened.progress()["state"] == "done" and opened.progress()["fraction"] == 1.0
    assert opened.last_message.text.startswith("quantification finished")
    # Maps kept: the overlay and vectors are drawn on the video. The warm blob
    # (conftest) is centred on y = H - 4 - t and rises 1 px per frame: the
    # overlay covers it, not the far corner, and the arrows point up.
    opened.seek(3)
    over = opened.render_overlay()
    assert over is not None and over[H - 7, W // 2, 3] > 0.3 and over[0, 0, 3] == 0.0
    tails, heads, _ = opened.vectors(spacing=4)
    assert len(tails) > 0 and np.all(heads[:, 1] < tails[:, 1])
    # The read-out under the cursor is the result's value at that pixel.
    r = opened.readout(W / 2, H - 7)
    u, v = r["velocity_px_per_frame"]
    mu, mv = opened.result.maps(3)["velocity_px_per_frame"]
    assert (u, v) == (pytest.approx(mu[H - 7, W // 2]), pytest.approx(mv[H - 7, W // 2]))
    assert v < -0.5 and abs(u) < 0.5 * abs(v)
    # 1 px/frame is the pixel footprint (3 m x 1 mrad) times the frame rate.
    assert r["velocity_m_s"][1] == pytest.approx(v * 3.0 * 1e-3 * RATE_HZ)
    # The run's minimum-detectable column is the other overlay: one map for
    # every frame, drawn wherever the background has contrast with the gas.
    mdc = opened.result.min_detectable_column("CH4")
    assert mdc.shape == (H, W) and np.all(np.isfinite(mdc)) and np.all(mdc > 0)
    assert opened.set_display(overlay_kind="minimum-detectable column")
    opened.seek(0)  # no maps kept here: the map is the run's, not the frame's
    over = opened.render_overlay()
    assert over is not None and np.all(over[..., 3] == pytest.approx(0.6))
    assert not opened.set_display(overlay_kind="nope")
    assert "overlay must be one of" in errors(opened)[-1]


def test_progress_is_visible_while_running_and_cancel_keeps_the_partial_result(opened, api):
    api.hold()
    opened.add_surface([(4, 12), (28, 12)])
    assert opened.start_run()
    assert opened.busy and not opened.poll()
    assert not opened.start_run()
    assert "already running" in errors(opened)[-1]
    assert not opened.open(opened.recording_path)
    assert "still running" in errors(opened)[-1]
    # The pipeline's reports show in the progress bar as they come, until
    # the frames read reach the third (they are read in blocks).
    import re

    def frames_read(message):
        m = re.search(r"frame (\d+)/", message)
        return int(m.group(1)) if m else 0

    seen = []
    while not seen or frames_read(seen[-1][1]) < 3:
        fraction, message = api.step()
        snap = opened.progress()
        assert snap["state"] == "running" and (snap["fraction"], snap["message"]) == (
            pytest.approx(fraction),
            message,
        )
        seen.append((fraction, message))
    assert len(seen) >= 4 and [f for f, _ in seen] == sorted(f for f, _ in seen)
    assert opened.cancel_run()
    api.release()
    run_to_end(opened)
    assert opened.progress()["state"] == "cancelled"
    assert opened.result is not None and opened.result_partial
    assert not opened.result.complete
    # The partial result covers the frames finished before the cancel.
    assert 3 <= len(opened.result.surfaces[0].species["CH4"].time_s) < T
    assert "partial result" in opened.last_message.text


def test_run_error_paths(vm, opened, api):
    assert not opened.start_run()
    assert "draw at least one control surface" in errors(opened)[-1]
    opened.add_surface([(4, 12), (28, 12)])
    opened.update_settings(velocity="wind", wind_speed_m_s="")
    assert not opened.start_run()
    assert "wind speed" in errors(opened)[-1] and opened.field_errors["wind_speed_m_s"]
    opened.update_settings(velocity="fluid")
    # The pipeline's own check, reported against the field it names.
    opened.update_settings(species={"CH4": True, "CO2": False, "Xe2": True})
    assert not opened.start_run()
    assert "Xe2" in opened.field_errors["species"]
    opened.update_settings(species={"CH4": True})
    # An error inside the run: a readable message, the window carries on.
    api.fail_at = 2
    api.fail_with = qogi.RecordingError("x.h5", "/frames", "unreadable chunk", "re-copy the file")
    assert opened.start_run()
    run_to_end(opened)
    assert "unreadable chunk" in errors(opened)[-1] and opened.result is None
    api.fail_with = ZeroDivisionError("division by zero")
    assert opened.start_run()
    run_to_end(opened)
    assert "internal error (ZeroDivisionError" in errors(opened)[-1]


def test_run_without_recording(vm):
    assert not vm.start_run()
    assert "open a recording" in errors(vm)[-1]
    assert not vm.cancel_run()


def test_result_goes_stale_when_inputs_change(opened):
    opened.add_surface([(4, 12), (28, 12)])
    opened.start_run()
    run_to_end(opened)
    assert not opened.result_stale
    opened.move_vertex(0, 0, 5, 12)
    assert opened.result_stale


# ---------------------------------------------------------------------- export


@pytest.fixture
def with_result(opened):
    opened.add_surface([(4, 12), (28, 12)], name="A")
    opened.start_run()
    run_to_end(opened)
    return opened


def test_export_everything(with_result, tmp_path):
    vm = with_result
    out = tmp_path / "out"
    out.mkdir()
    assert vm.export_all(out, stem="run")
    names = sorted(p.name for p in out.iterdir())
    assert names == [
        "run.csv",
        "run.json",
        "run.summary.csv",
        "run_frame.png",
        "run_rates.png",
        "run_rates_maps.png",
        "run_report.md",
        "run_report.pdf",
    ]
    assert (out / "run_report.pdf").read_bytes()[:5] == b"%PDF-"
    d = json.loads((out / "run.json").read_text())
    assert d["surfaces"][0]["species"]["CH4"]["mean_kg_h"] == pytest.approx(
        vm.result.surfaces[0].species["CH4"].mean_kg_h
    )
    import cv2

    img = cv2.imread(str(out / "run_frame.png"))
    assert img.shape == (3 * H, 3 * W, 3)
    report = (out / "run_report.md").read_text()
    assert "| A | CH4 |" in report and "test camera" in report and "run.csv" in report
    assert "detection limit [kg/h]" in report
    assert vm.store.last_dir == str(out)


def test_export_errors(vm, with_result, tmp_path):
    assert not with_result.export_csv(tmp_path / "nowhere" / "x.csv")
    assert "does not exist" in errors(with_result)[-1]
    assert not with_result.export_frame(tmp_path / "frame.jpg")
    assert "PNG" in errors(with_result)[-1]
    assert not with_result.export_json(tmp_path)
    assert "is a folder" in errors(with_result)[-1]


def test_export_needs_a_result(opened, tmp_path):
    for fn in (opened.export_csv, opened.export_json, opened.export_plots, opened.export_report):
        assert not fn(tmp_path / "x.out")
        assert "run the quantification first" in errors(opened)[-1]
    assert opened.export_frame(tmp_path / "frame.png")  # the frame needs no result


# ---------------------------------------------------------------------- demo


def test_demo_is_made_in_the_background_then_opened(vm, rec_path):
    assert vm.open_demo()
    run_to_end(vm)
    assert vm.recording is not None and vm.recording_path == str(rec_path)


def test_demo_failure_is_a_message(api, store):
    def broken(progress):
        raise OSError("disk full")

    v = ViewModel(api=api, store=store, demo_provider=broken)
    v.open_demo()
    run_to_end(v)
    assert "making the demo scene failed: disk full" in errors(v)[-1]


# ---------------------------------------------------------------------- helpers


def test_finite_segments_split_at_gaps():
    segs = results.finite_segments([0, 1, 2, 3, 4, 5], [1, np.nan, 2, 3, np.nan, np.nan])
    assert [list(x) for x, _ in segs] == [[0.0], [2.0, 3.0]]


def test_vector_field_scale_and_mask():
    u = np.zeros((20, 30))
    v = np.full((20, 30), -2.0)
    w = np.zeros((20, 30))
    w[:, 10:20] = 1.0
    tails, heads, scale = results.vector_field(u, v, weight=w, spacing=5, target_px=4.0)
    assert np.all((tails[:, 0] >= 10) & (tails[:, 0] < 20))
    np.testing.assert_allclose(heads - tails, np.tile([0.0, -4.0], (len(tails), 1)))
    assert scale == pytest.approx(2.0)


def test_arrow_segments_draw_shaft_and_head():
    xs, ys = results.arrow_segments(
        np.array([[0.0, 0.0], [1.0, 1.0]]), np.array([[0.0, -10.0], [1.0, 1.0]]), head_frac=0.3
    )
    assert len(xs) == 6  # the zero-length arrow is skipped: 3 segments of 2 points
    assert (xs[0], ys[0], xs[1], ys[1]) == (0.0, 0.0, 0.0, -10.0)
    # Both head strokes start at the head, go back 3 px at +-25 deg.
    for k in (3, 5):
        dx, dy = xs[k] - xs[k - 1], ys[k] - ys[k - 1]
        assert np.hypot(dx, dy) == pytest.approx(3.0)
        assert np.degrees(np.arctan2(abs(dx), dy)) == pytest.approx(25.0)


def test_demo_file_name_names_its_definition(tmp_path):
    from qogi_gui import demo

    p = demo.demo_path(tmp_path)
    assert p.parent == tmp_path
    assert demo.DEMO["preset"] in p.name and f"seed{demo.DEMO['seed']}" in p.name
    from qogi.contract import VERSION

    assert p.name.endswith(f"qogi{qogi.__version__}.v{VERSION}.h5")  # qogi and format version
    x, y = demo.source_pixel()
    assert 0 <= x < 320 and 0 <= y < 256


def test_cancelling_the_demo_leaves_nothing_behind(api, store, tmp_path, monkeypatch):
    from qogi.synth import render
    from qogi_gui import demo

    started = threading.Event()

    def fake_synthesize(preset, path, progress=None, **kw):
        # What qogi.synth.render.synthesize does: write, report, and raise
        # KeyboardInterrupt when the progress callback returns False.
        with open(path, "wb") as f:
            f.write(b"partial")
        started.set()
        while progress(0.5, "frame 1/2") is not False:
            pass
        raise KeyboardInterrupt("cancelled")

    monkeypatch.setattr(render, "synthesize", fake_synthesize)
    v = ViewModel(
        api=api, store=store, demo_provider=lambda progress: demo.ensure_demo(progress, tmp_path)
    )
    v.open_demo()
    assert started.wait(5)
    assert v.progress()["message"].startswith("demo scene: frame 1/2")
    v.cancel_run()
    run_to_end(v)
    assert v.progress()["state"] == "cancelled"
    assert "cancelled" in v.last_message.text and v.recording is None
    assert list(tmp_path.iterdir()) == []


def test_maps_of_part_of_the_frame_are_placed_by_their_origin():
    maps = {
        "origin": (3, 2),
        "column_density_kg_m2": {"CH4": np.ones((2, 4), np.float32)},
        "velocity_px_per_frame": (np.zeros((2, 4)), np.full((2, 4), -1.0)),
        "status": np.zeros((2, 4), np.uint8),
    }
    full = results.full_frame_maps(maps, (6, 8))
    col = full["column_density_kg_m2"]["CH4"]
    assert col.shape == (6, 8)
    assert np.all(col[2:4, 3:7] == 1) and np.isnan(col[0, 0]) and np.isnan(col[4, 3])
    assert full["velocity_px_per_frame"][1][3, 6] == -1 and np.isnan(
        full["velocity_px_per_frame"][1][3, 7]
    )
    assert full["status"][2, 3] == 0 and full["status"][0, 0] == -1
    # Maps that already cover the frame are left alone.
    same = results.full_frame_maps({"column_density_kg_m2": {"CH4": col}}, (6, 8))
    assert same["column_density_kg_m2"]["CH4"] is col


def test_frame_picture_draws_the_surfaces_where_they_are(opened):
    opened.add_surface([(4, 12), (28, 12)], name="A")
    opened.set_display(colormap="gray")
    img = opened.frame_picture(zoom=3)
    assert img.shape == (3 * H, 3 * W, 3) and img.dtype == np.uint8
    cyan = np.abs(img.astype(int) - np.array([0, 220, 255])).sum(axis=2) < 40
    line_row = (12 + 0.5) * 3
    rows = np.flatnonzero(cyan[:, 3 * 16])  # the column through the line's middle
    assert np.any(np.abs(rows - line_row) <= 2)  # the line
    assert np.any(rows < line_row - 10)  # its arrow points up ...
    assert not np.any(rows > line_row + 3)  # ... not down
    assert cyan[int(line_row), 3 * 5]  # the line away from the arrow
    # Away from the line, the surface colour does not appear (grey video only).
    assert not cyan[:, 3 * 2].any()


def test_open_in_the_background(vm, rec_path, tmp_path):
    assert vm.open(rec_path, background=True)
    assert vm.busy or vm.job is not None
    run_to_end(vm)
    assert vm.recording is not None and vm.recording.n_frames == T
    assert vm.open(tmp_path / "gone.h5", background=True)
    run_to_end(vm)
    assert "does not exist" in errors(vm)[-1]
    assert vm.recording is not None  # the open recording stays


def test_step_between_frames_with_maps(opened, api):
    opened.add_surface([(4, 12), (28, 12)])
    # Five frames: the fewest the velocimetry gives a rate from (qogi.pipeline.checks).
    opened.update_settings(frame_start="2", frame_stop="7")
    opened.start_run()
    run_to_end(opened)
    assert opened.map_frames() == [2, 3, 4, 5, 6]
    opened.seek(0)
    assert opened.render_overlay() is None  # frame 0 was not analysed
    assert opened.seek_map_frame(1) and opened.frame == 2
    opened.seek(6)
    assert opened.seek_map_frame(1) and opened.frame == 2  # wraps around
    assert opened.seek_map_frame(-1) and opened.frame == 6
    assert opened.render_overlay() is not None


def test_map_keys_are_placed_on_recording_frames():
    from types import SimpleNamespace as NS

    # Keyed by the position within frames 5..8 (the pipeline now) or by the
    # recording's frame index (docs/pipeline_api.md): the same frames either way.
    positional = NS(map_frames=[0, 2], config=NS(frames=(5, 9)))
    absolute = NS(map_frames=[5, 7], config=NS(frames=(5, 9)))
    assert results.map_frame_keys(positional) == {5: 0, 7: 2}
    assert results.map_frame_keys(absolute) == {5: 5, 7: 7}
    assert results.map_frame_keys(NS(map_frames=[0, 3], config=NS(frames=None))) == {0: 0, 3: 3}
    assert results.map_frame_keys(NS(map_frames=[], config=NS(frames=(5, 9)))) == {}


def test_automatic_surfaces_cross_the_rising_blob_and_set_the_source(opened):
    # The test recording's warm blob rises up the middle column (x = 16): the
    # surfaces must cross it horizontally at the asked distances from the
    # detected source on that column, which becomes the analysis source.
    assert opened.auto_surfaces([3, 6])
    assert len(opened.surfaces) == 2
    assert opened.settings.use_source
    sx, sy = float(opened.settings.source_x), float(opened.settings.source_y)
    assert abs(sx - W / 2) < 3
    for s, d in zip(opened.surfaces, (3, 6)):
        (x0, y0), (x1, y1) = s.points[0], s.points[-1]
        assert abs(y1 - y0) < abs(x1 - x0)  # across the rise
        assert min(x0, x1) < W / 2 < max(x0, x1)
        assert abs(abs(0.5 * (y0 + y1) - sy) - d) < 1.5
    # Again: new names, nothing replaced; bad input is an error message.
    assert opened.auto_surfaces([4])
    assert len({s.name for s in opened.surfaces}) == 3
    assert not opened.auto_surfaces([])
    assert not opened.auto_surfaces(["x"])
    assert any("distances" in e for e in errors(opened))
