"""Camera files end to end through `qogi.open_recording`, `qogi quantify`,
`qogi info` and `qogi convert`: FLIR .seq written by qogi's own writer from a
synthetic MWIR release with exact truth, the shared long-wave FLIR samples,
and the refusals when a scene fact is missing or the camera's band is not the
file's."""

from __future__ import annotations

import json
import math
import struct

import numpy as np
import pytest

import qogi
from qogi.apps.cli import main
from qogi.errors import UsageError
from qogi.io.flir import FlirFile, flir_apparent_temperature
from qogi.io.flir_writer import (
    flir_metadata,
    planck_calibration_for,
    raw_from_apparent_temperature,
    write_flir_seq,
    write_recording_as_seq,
)
from qogi.pipeline.surfaces import truth_surfaces
from qogi.synth import render

LAB = "lab-ch4-5slpm-gf320"


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """One second of a 5 SLPM methane release seen by the GF320-like camera
    (exact truth), in HDF5 and as a FLIR .seq written by qogi's writer with
    GF320-like Planck constants (B = c2 x the channel's centroid, 3.3 um) and
    each frame's own time stamp; the file's object distance is FLIR's
    default 1 m, its atmosphere the scene's."""
    d = tmp_path_factory.mktemp("lab")
    h5 = d / "lab.h5"
    render.synthesize(LAB, h5, duration_s=1.0, seed=4)
    seq = d / "lab.seq"
    with qogi.open_recording(h5) as rec:
        write_recording_as_seq(rec, seq, object_distance_m=1.0)
    return h5, seq


def _surface_args(h5):
    with qogi.open_recording(h5) as rec:
        surfs, source = truth_surfaces(rec, heights_m=[0.08], half_width_px=50)
    pts = ",".join(f"{v:g}" for p in surfs[0].points for v in p)
    return ["--surface", pts, "--source", f"{source[0]:g},{source[1]:g}"]


# ------------------------------------------------------------------ the writer


def _metadata_3030(width, height, timestamp_s=0.0, frame_rate_hz=15):
    """FLIR metadata of a width x height camera with the 3030 cm-1 one-line
    Planck calibration and a 20 degree field of view."""
    return flir_metadata(
        width=width,
        height=height,
        timestamp_s=timestamp_s,
        planck=planck_calibration_for(3030.0),
        field_of_view_deg=20.0,
        frame_rate_hz=frame_rate_hz,
    )


def test_writer_lays_out_fff_blocks_at_the_documented_offsets(tmp_path):
    planck = planck_calibration_for(3030.0)
    m = flir_metadata(
        width=4,
        height=3,
        timestamp_s=1700000000.25,
        planck=planck,
        field_of_view_deg=24.0,
        frame_rate_hz=15,
        object_distance_m=7.5,
        atmospheric_temperature_K=280.0,
    )
    raw = np.arange(12, dtype=np.uint16).reshape(3, 4) + 1000
    p = tmp_path / "one.seq"
    write_flir_seq(p, [raw], [m])
    b = p.read_bytes()
    # FFF header: magic, version 100 (big-endian), directory at 0x40 with 2 entries.
    assert b[:4] == b"FFF\x00"
    assert struct.unpack(">III", b[0x14:0x20]) == (100, 0x40, 2)
    rtype, _, _, _, raw_off, raw_len = struct.unpack(">HHIIII", b[0x40:0x54])
    ctype, _, _, _, cam_off, _ = struct.unpack(">HHIIII", b[0x60:0x74])
    assert (rtype, ctype) == (0x01, 0x20)
    # RawData: byte-order mark 2 (little-endian), width, height, then the words.
    assert struct.unpack("<HHH", b[raw_off : raw_off + 6]) == (2, 4, 3)
    assert raw_len == 32 + 2 * 12
    np.testing.assert_array_equal(np.frombuffer(b[raw_off + 32 : raw_off + 56], "<u2"), raw.ravel())
    # CameraInfo: distance at 0x24, atmosphere at 0x2C, B at 0x5C, FOV at 0x1B4,
    # time stamp (s, ms) at 0x384.
    cam = b[cam_off:]
    assert struct.unpack("<f", cam[0x24:0x28])[0] == pytest.approx(7.5)
    assert struct.unpack("<f", cam[0x2C:0x30])[0] == pytest.approx(280.0)
    assert struct.unpack("<f", cam[0x5C:0x60])[0] == pytest.approx(1.438776877 * 3030.0, rel=1e-6)
    assert struct.unpack("<f", cam[0x1B4:0x1B8])[0] == pytest.approx(24.0)
    assert struct.unpack("<II", cam[0x384:0x38C]) == (1700000000, 250)


@pytest.mark.parametrize("order", ["<", ">"])
def test_little_and_big_endian_raw_data_read_the_same_counts(tmp_path, order):
    m = _metadata_3030(5, 2, timestamp_s=1.7e9, frame_rate_hz=30)
    raw = np.array([[0, 1, 258, 40000, 65535], [7, 8, 9, 10, 11]], np.uint16)
    p = tmp_path / f"{'le' if order == '<' else 'be'}.seq"
    write_flir_seq(p, [raw], [m], byte_order=order, header_order=order)
    with FlirFile(p) as f:
        fr = f.frame(0)
    np.testing.assert_array_equal(fr.raw, raw)
    assert fr.metadata.raw_format == ("raw-le" if order == "<" else "raw-be")
    assert fr.metadata.planck_b == pytest.approx(m.planck_b, rel=1e-6)


def test_counts_invert_the_one_line_planck_law_to_the_count():
    m = _metadata_3030(1, 1)
    t = np.linspace(270.0, 340.0, 701)
    raw = raw_from_apparent_temperature(t, m)
    back = flir_apparent_temperature(raw, m)
    # Half a count of the calibration's slope dT/draw = 1 / (raw B / T^2).
    slope = 1.0 / ((raw.astype(float) + m.planck_o) * m.planck_b / t**2)
    assert np.all(np.abs(back - t) <= 0.5 * slope * 1.01)


def test_a_block_without_camera_info_is_refused_by_name(tmp_path):
    from qogi.io.flir_writer import fff_block

    m = _metadata_3030(2, 2)
    block = bytearray(fff_block(np.zeros((2, 2), np.uint16), m))
    struct.pack_into(">H", block, 0x60, 0x22)  # the CameraInfo entry becomes another type
    p = tmp_path / "nocal.seq"
    p.write_bytes(bytes(block))
    with pytest.raises(ValueError, match="no CameraInfo record: no calibration constants"):
        qogi.open_recording(p, camera="gf320", distance_m=2.0)


# ------------------------------------------------------------------ opening


def test_seq_opens_lazily_with_per_frame_times_and_scene_origins(lab):
    h5, seq = lab
    with qogi.open_recording(h5) as ref, qogi.open_recording(seq, camera="gf320") as rec:
        assert rec.shape == ref.shape and not rec.in_memory
        # Frame times from each frame's stamp (FLIR stores milliseconds).
        np.testing.assert_allclose(rec.time_s, ref.time_s, atol=0.6e-3)
        # Counts -> apparent temperature -> radiance through the gf320 channel:
        # the release's radiance to the quantization of the counts: half a
        # count is up to 2.3 mK at the 285 K plate, where dL/L = B dT / T^2 is
        # 1.2e-4.
        np.testing.assert_allclose(
            rec.frames(0, 5, quantity="radiance"), ref.frames(0, 5), rtol=1.3e-4
        )
        assert rec.camera.ifov_rad == pytest.approx(ref.camera.ifov_rad, rel=1e-6)
        assert rec.scene_origin["distance_m"] == "file (FLIR object distance)"
        assert rec.scene_origin["ambient_temperature_K"] == "file (FLIR atmospheric temperature)"
        assert rec.scene_origin["pressure_Pa"].startswith("assumed")
        # FLIR's factory-default distance is used but flagged, and so is the pressure.
        codes = rec.warnings.codes()
        assert codes.count("scene-camera-default") == 1 and "scene-pressure-assumed" in codes
        assert "1 m is FLIR's factory default" in rec.warnings[0].message


def test_dropped_frames_are_seen_in_the_time_stamps(tmp_path):
    m = dict(
        width=3,
        height=2,
        planck=planck_calibration_for(3030.0),
        field_of_view_deg=0.2,
        frame_rate_hz=30,
    )
    times = 1.7e9 + np.array([0, 1, 2, 4, 5, 8]) / 30.0
    metas = [flir_metadata(timestamp_s=t, **m) for t in times]
    p = tmp_path / "gaps.seq"
    write_flir_seq(p, [np.full((2, 3), 20000, np.uint16)] * 6, metas)
    with qogi.open_recording(p, camera="gf320", distance_m=3.0) as rec:
        np.testing.assert_allclose(rec.time_s, (times - times[0]), atol=0.6e-3)
        assert rec.camera.frame_rate_hz == pytest.approx(30.0, rel=0.01)
        [drop] = [w for w in rec.warnings if w.code == "frames-dropped"]
        assert drop.data["missing"] == 3 and drop.data["first_gap_after_frame"] == 2


def test_missing_camera_is_refused_naming_it_and_why(lab):
    _, seq = lab
    with pytest.raises(
        UsageError,
        match=r"the camera \(spectral response\) is needed and the "
        r"file does not hold it.*--camera",
    ):
        qogi.open_recording(seq)


def test_the_long_wave_samples_refuse_a_gas_camera_naming_both_bands(flir_samples):
    for name in ("SampleCSQ.csq", "SampleSEQ.seq", "IR_2412.jpg"):
        with pytest.raises(UsageError) as e:
            qogi.open_recording(flir_samples / name, camera="gf320", distance_m=3.0)
        msg = str(e.value)
        assert "a long-wave (LWIR) camera" in msg
        assert "calibrated near 9.5 um" in msg or "calibrated near 9.6 um" in msg
        assert "'gf320' given sees 3.20-3.40 um" in msg


def test_the_samples_open_with_their_band_and_times(flir_samples):
    lwir = qogi.SpectralResponse.from_wavelength_um([7.5, 13.0], [1.0, 1.0], "LWIR")
    with qogi.open_recording(flir_samples / "SampleCSQ.csq", camera=lwir, distance_m=3.0) as rec:
        # The .csq's stamps, ms resolution, 30 Hz nominal: 33-34 ms apart.
        assert rec.n_frames == 8 and np.all(np.round(np.diff(rec.time_s) * 1e3) >= 33)
        assert rec.scene.distance_m == 3.0 and rec.scene_origin["distance_m"] == "given"
        with FlirFile(flir_samples / "SampleCSQ.csq") as f:
            fr = f.frame(3)
        np.testing.assert_allclose(rec.frame(3)[0], fr.apparent_temperature(), rtol=1e-6)


@pytest.fixture(scope="module")
def flir_samples(shared_dir):
    d = shared_dir / "samples" / "flir"
    if not d.is_dir():
        pytest.skip(f"FLIR samples not found in {d}")
    return d


# ------------------------------------------------------------------ command line


def test_quantify_seq_reads_the_same_rate_as_the_hdf5_release(lab, tmp_path, capsys):
    h5, seq = lab
    surf = _surface_args(h5)
    common = surf + ["--wind-speed", "0.5", "-q"]
    assert main(["quantify", str(h5), "--json", str(tmp_path / "a.json")] + common) == 0
    assert (
        main(
            [
                "quantify",
                str(seq),
                "--camera",
                "gf320",
                "--distance",
                "1.5",
                "--json",
                str(tmp_path / "b.json"),
            ]
            + common
        )
        == 0
    )
    a = json.loads((tmp_path / "a.json").read_text())
    b = json.loads((tmp_path / "b.json").read_text())
    ra = a["surfaces"][0]["species"]["CH4"]["mean_kg_h"]
    rb = b["surfaces"][0]["species"]["CH4"]["mean_kg_h"]
    print(
        f"CH4 at 8 cm, wind 0.5 m/s: HDF5 {ra:.5g} kg/h, FLIR .seq {rb:.5g} kg/h "
        f"({rb / ra - 1:+.3%})"
    )
    assert ra > 0 and rb == pytest.approx(ra, rel=0.01)
    codes = [w["code"] for w in b["warnings"]]
    # The distance was given: no default flagged; the pressure was assumed.
    assert "scene-pressure-assumed" in codes and "scene-camera-default" not in codes
    assert b["info"]["scene_origin"]["distance_m"] == "given"


def test_quantify_refuses_a_camera_file_without_camera(lab, capsys):
    _, seq = lab
    assert main(["quantify", str(seq), "--surface", "1,1,5,5"]) == 2
    err = capsys.readouterr().err
    assert "the camera (spectral response) is needed" in err and "--camera" in err


def test_quantify_refuses_the_lwir_sample_with_the_gf320(flir_samples, capsys):
    assert (
        main(
            [
                "quantify",
                str(flir_samples / "SampleCSQ.csq"),
                "--camera",
                "gf320",
                "--distance",
                "3",
                "--surface",
                "1,1,50,50",
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "9.5 um" in err and "3.20-3.40 um" in err


def test_convert_streams_to_a_recording_that_quantifies_the_same(lab, tmp_path, capsys):
    h5, seq = lab
    out = tmp_path / "conv.h5"
    assert (
        main(["convert", str(seq), "-o", str(out), "--camera", "gf320", "--distance", "1.5", "-q"])
        == 0
    )
    with (
        qogi.open_recording(out) as conv,
        qogi.open_recording(seq, camera="gf320", distance_m=1.5) as rec,
    ):
        np.testing.assert_array_equal(conv.to_array(), rec.to_array())
        np.testing.assert_array_equal(conv.time_s, rec.time_s)
        assert conv.scene.distance_m == 1.5
        assert conv.attrs["origin_distance_m"] == "given"
        assert "scene-pressure-assumed" in conv.attrs["source_warnings"]
    # No temporary file is left beside the output.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["conv.h5"]


def test_convert_refuses_before_writing_when_a_fact_is_missing(lab, tmp_path, capsys):
    _, seq = lab
    out = tmp_path / "never.h5"
    assert main(["convert", str(seq), "-o", str(out)]) == 2
    assert not out.exists() and "--camera" in capsys.readouterr().err


def test_info_says_what_a_conversion_needs(lab, capsys):
    _, seq = lab
    assert main(["info", str(seq)]) == 0
    out = capsys.readouterr().out
    assert "to quantify or convert: give --camera" in out
    assert "distance_m = 1 is FLIR's factory default" in out
    assert main(["info", str(seq), "--camera", "gf320", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["needs"]["needs"] == ["camera"]
    assert info["recording"]["scene_origin"]["distance_m"] == "file (FLIR object distance)"
    assert math.isclose(info["needs"]["holds"]["band_um"], 1e4 / 3033.1, rel_tol=1e-3)


# ------------------------------------------------------------ damaged frames


def _three_frame_seq(path):
    m = dict(width=3, height=2, planck=planck_calibration_for(3030.0), field_of_view_deg=0.2)
    metas = [flir_metadata(timestamp_s=1.7e9 + k / 30.0, frame_rate_hz=30, **m) for k in range(3)]
    write_flir_seq(path, [np.full((2, 3), 20000 + k, np.uint16) for k in range(3)], metas)
    return path


def _damage_header(path, frame):
    data = bytearray(path.read_bytes())
    starts = [i for i in range(len(data)) if data[i : i + 4] == b"FFF\0"]
    data[starts[frame] : starts[frame] + 4] = b"XXXX"
    path.write_bytes(bytes(data))
    return starts


def test_a_frame_with_a_damaged_header_is_reported_not_skipped_silently(tmp_path, capsys):
    """A .seq whose second frame's header is damaged: qogi info said 1 frame
    for a 2-frame file and qogi convert wrote it, exit 0, without a word."""
    p = _three_frame_seq(tmp_path / "three.seq")
    starts = _damage_header(p, 1)
    with FlirFile(p) as f:
        assert len(f) == 2 and [f.frame(i).raw[0, 0] for i in range(2)] == [20000, 20002]
        [msg] = f.damaged
    assert f"frame 1 (bytes {starts[1]}-{starts[2]}" in msg and "b'XXXX'" in msg
    with qogi.open_recording(p, camera="gf320", distance_m=3.0) as rec:
        assert rec.n_frames == 2
        [w] = [w for w in rec.warnings if w.code == "frames-damaged"]
        assert w.message == msg
    assert main(["info", str(p)]) == 0
    assert f"warning: {msg}" in capsys.readouterr().out
    out = tmp_path / "three.h5"
    assert main(["convert", str(p), "-o", str(out), "--camera", "gf320", "--distance", "3"]) == 0
    assert "qogi convert: warning: [frames-damaged]" in capsys.readouterr().err
    with qogi.open_recording(out) as rec:
        assert rec.n_frames == 2 and "frames-damaged" in rec.attrs["source_warnings"]


def test_padding_between_frames_is_not_damage(tmp_path):
    p = _three_frame_seq(tmp_path / "three.seq")
    data = p.read_bytes()
    second = data.index(b"FFF\0", 1)
    p.write_bytes(data[:second] + bytes(512) + data[second:])  # zeros between blocks
    with FlirFile(p) as f:
        assert len(f) == 3 and f.damaged == []


def test_a_damaged_first_header_is_bad_data(tmp_path, capsys):
    p = _three_frame_seq(tmp_path / "three.seq")
    _damage_header(p, 0)
    assert main(["info", str(p)]) == 3
    assert "not a FLIR radiometric file" in capsys.readouterr().err


def test_the_flir_sample_with_its_second_header_damaged(flir_samples, tmp_path, capsys):
    p = tmp_path / "SampleSEQ.seq"
    p.write_bytes((flir_samples / "SampleSEQ.seq").read_bytes())
    _damage_header(p, 2)  # 0, a stray 'FFF\0' inside frame 0's counts, then frame 1
    assert main(["info", str(p)]) == 0
    out = capsys.readouterr().out
    assert "(seq, 1 frames" in out and "warning: " in out and "frame 1 (bytes 617180-" in out
