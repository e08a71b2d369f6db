"""Every way of calling qogi wrongly gets one line naming the problem and the
fix, with exit 2 (usage) or 3 (bad data), before any work; never a traceback
and never a damaged input. Each case is an example from issue 16."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest
from patching import replace_everywhere
from test_interrupt import SURFACE, small_recording

from qogi import errors
from qogi.apps import cli
from qogi.errors import EXIT_DATA, EXIT_INTERNAL, EXIT_USAGE


def run(capsys, *argv):
    """qogi ARGV in this process: (exit status, stdout, stderr)."""
    try:
        code = cli.main([str(a) for a in argv])
    except SystemExit as e:  # argparse's own usage errors
        code = e.code
    out, err = capsys.readouterr()
    return code, out, err


def one_line_error(err, command):
    lines = [ln for ln in err.strip().splitlines() if ln.startswith(f"qogi {command}: error:")]
    assert lines and "Traceback" not in err, err
    return lines[-1]


@pytest.fixture
def rec(tmp_path):
    return small_recording(tmp_path / "rec.h5", n_frames=8)


@pytest.fixture
def no_work(monkeypatch):
    """Fails the test if a command starts computing."""
    import qogi.physics.spectra
    import qogi.pipeline
    import qogi.synth.render

    def boom(*a, **k):
        raise AssertionError("the command computed before checking its arguments")

    for real in (
        qogi.pipeline.quantify,
        qogi.synth.render.synthesize,
        qogi.physics.spectra.cross_section,
        qogi.physics.spectra.load_line_list,
    ):
        replace_everywhere(monkeypatch, real, boom)


# ----------------------------------------------------------------- xsec


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--range", "3000", "2900"], "MAX must be greater than MIN"),
        (["--range", "2900"], "--range: expected 2 arguments"),
        (["--range", "a", "b"], "not a number"),
        (["--range", "2900", "3000", "--step", "-1"], "--step: must be > 0"),
        (["--range", "2900", "3000", "--step", "nan"], "--step: must be a finite number"),
        (["--range", "2900", "3000", "--temperature", "-5"], "--temperature: must be > 0"),
        (["--range", "2900", "3000", "--pressure", "0"], "--pressure: must be > 0"),
        (["--range", "2900", "3000", "--self-fraction", "2"], "within [0, 1]"),
        (["--range", "2900", "3000", "--cutoff", "-3"], "--cutoff"),
        (["--range", "0", "1e9", "--step", "1e-3"], "at most 5e7"),
        (["--range", "2900", "3000", "--out", "x.txt"], "give a .npz or .csv"),
    ],
)
def test_xsec_argument_errors_are_usage_errors_before_any_work(
    capsys, no_work, tmp_path, monkeypatch, args, needle
):
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, "xsec", "CH4", *args)
    assert code == EXIT_USAGE and needle in err and "Traceback" not in err, err


def test_xsec_unknown_species_and_missing_line_lists(capsys, tmp_path, monkeypatch):
    code, _, err = run(capsys, "xsec", "XYZ", "--range", "2900", "3000")
    assert code == EXIT_USAGE and "HITRAN molecule formula" in one_line_error(err, "xsec")
    # N2O is a species qogi knows (partition sums) but has no line list here.
    monkeypatch.setenv("QOGI_HITRAN_PATH", str(tmp_path))
    monkeypatch.setenv("QOGI_CACHE_DIR", str(tmp_path / "cache"))
    code, _, err = run(capsys, "xsec", "N2O", "--range", "2200", "2210")
    line = one_line_error(err, "xsec")
    assert code == EXIT_USAGE and "no HITRAN line list for 'N2O'" in line
    assert "qogi hitran fetch N2O" in line  # how to fix it
    code, _, err = run(
        capsys, "xsec", "CH4", "--range", "2900", "3000", "--line-list", tmp_path / "nope.par"
    )
    assert code == EXIT_USAGE and "nope.par" in one_line_error(err, "xsec")


def test_xsec_unwritable_output_fails_before_computing(capsys, no_work, tmp_path):
    code, _, err = run(
        capsys, "xsec", "CH4", "--range", "2900", "3000", "--out", tmp_path / "missing" / "x.npz"
    )
    assert code == EXIT_USAGE and "does not exist" in one_line_error(err, "xsec")


# ----------------------------------------------------------------- synth


def test_synth_into_a_missing_folder_fails_before_computing(capsys, no_work, tmp_path):
    code, _, err = run(
        capsys, "synth", "lab-ch4-5slpm-gf320", "-o", tmp_path / "missing_dir" / "x.h5"
    )
    line = one_line_error(err, "synth")
    assert code == EXIT_USAGE and "missing_dir does not exist" in line and "mkdir" in line


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--seed=-1"], "--seed: must be >= 0"),
        (["--seed", "1.5"], "--seed: not a whole number"),
        (["--duration", "0"], "--duration: must be > 0"),
        (["--frame-rate", "inf"], "--frame-rate: must be a finite number"),
        (["--threads", "-2"], "--threads: must be >= 0"),
        (["--camera", "no-such-camera"], "unknown camera preset"),
    ],
)
def test_synth_argument_errors(capsys, no_work, tmp_path, args, needle):
    code, _, err = run(capsys, "synth", "lab-ch4-5slpm-gf320", "-o", tmp_path / "x.h5", *args)
    assert code == EXIT_USAGE and needle in err and "Traceback" not in err, err
    code, _, err = run(capsys, "synth", "no-such-preset", "-o", tmp_path / "x.h5")
    assert code == EXIT_USAGE and "unknown preset" in one_line_error(err, "synth")


# ----------------------------------------------------------------- quantify


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--source", "5"], "--source: expected X,Y"),
        (["--source", "nan,nan"], "--source: must be a finite pixel position"),
        (["--source", "1,inf"], "--source: must be a finite pixel position"),
        (["--frames", "5"], "--frames: expected START:STOP"),
        (
            ["--frames", "5:2"],
            "--frames: must be (start, stop), whole numbers with 0 <= start < stop",
        ),
        (["--threads", "-3"], "--threads: must be >= 0"),
        (["--wind-speed", "-1"], "--wind-speed: must be within (0, 100] m/s; got -1"),
        (["--distance", "nan"], "--distance: must be a finite number"),
        (["--surface", "1,2"], "expected an even number"),
        (["--auto-surfaces", "a,b"], "--auto-surfaces"),
    ],
)
def test_quantify_argument_errors(capsys, rec, args, needle):
    surface = [] if "--surface" in args or "--auto-surfaces" in args else ["--surface", SURFACE]
    code, _, err = run(capsys, "quantify", rec, *surface, *args, "-q")
    assert code == EXIT_USAGE and needle in err and "Traceback" not in err, err


def test_quantify_never_writes_over_its_input(capsys, no_work, rec):
    before = rec.read_bytes()
    for opt in ("--json", "--csv", "--plot"):
        code, _, err = run(capsys, "quantify", rec, "--surface", SURFACE, opt, rec, "-q")
        assert code == EXIT_USAGE and "that is the input file" in one_line_error(err, "quantify")
    # The same file by another name is still the input.
    link = rec.with_name("alias.h5")
    os.link(rec, link)
    code, _, err = run(capsys, "quantify", rec, "--surface", SURFACE, "--json", link, "-q")
    assert code == EXIT_USAGE and "input file" in err
    assert rec.read_bytes() == before


def test_quantify_refuses_two_outputs_on_one_file(capsys, no_work, rec, tmp_path):
    x = tmp_path / "x.out"
    code, _, err = run(capsys, "quantify", rec, "--surface", SURFACE, "--json", x, "--csv", x, "-q")
    assert code == EXIT_USAGE and "both name" in one_line_error(err, "quantify")
    assert not x.exists()


@pytest.mark.parametrize("where", ["missing-folder", "proc"])
def test_quantify_unwritable_output_fails_before_computing(capsys, no_work, rec, tmp_path, where):
    if where == "proc" and not os.path.isdir("/proc/self"):
        pytest.skip("no /proc here")
    target = tmp_path / "no" / "out.json" if where == "missing-folder" else "/proc/out.json"
    code, _, err = run(capsys, "quantify", rec, "--surface", SURFACE, "--json", target, "-q")
    assert code == EXIT_USAGE and "--json" in one_line_error(err, "quantify")


def test_missing_and_broken_recordings(capsys, tmp_path):
    code, _, err = run(capsys, "quantify", tmp_path / "missing.h5", "--surface", SURFACE)
    assert code == EXIT_USAGE and "missing.h5" in one_line_error(err, "quantify")
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(200))  # an HDF5 signature, then nothing
    code, _, err = run(capsys, "quantify", bad, "--surface", SURFACE)
    assert code == EXIT_DATA and "bad.h5" in one_line_error(err, "quantify")


@pytest.mark.parametrize(
    "shape, needle",
    [
        ((8, 1, 200000, 200000), "GiB per frame"),  # 149 GiB per frame
        ((10_000_000, 2, 24, 32), "the file stores"),  # 57 GiB of frames never written
    ],
)
def test_a_file_declaring_a_huge_shape_is_refused_before_reading(capsys, rec, shape, needle):
    with h5py.File(rec, "r+") as f:
        attrs = dict(f["frames"].attrs)
        del f["frames"]
        d = f.create_dataset("frames", shape=shape, dtype=np.float32, chunks=(1, 1, 24, 32))
        d.attrs.update(attrs)
        if shape[0] != 8:
            del f["time_s"]
            f.create_dataset("time_s", shape=(shape[0],), dtype=np.float64, chunks=(4096,))
    for cmd in (["info", rec], ["quantify", rec, "--surface", SURFACE, "-q"]):
        code, _, err = run(capsys, *cmd)
        assert code == EXIT_DATA and needle in one_line_error(err, cmd[0]), err


def test_blank_frames_are_refused_with_exit_3(capsys, rec):
    """All-zero radiance: no rate can come out; refused before any work, with
    or without a known background (it used to print "nan kg/h" with exit 0)."""
    with h5py.File(rec, "r+") as f:
        f["frames"][...] = 0.0
    code, _, err = run(capsys, "quantify", rec, "--surface", SURFACE, "-q")
    assert code == EXIT_DATA and "band_radiance" in one_line_error(err, "quantify")
    with h5py.File(rec, "r+") as f:
        f["scene"].attrs["background_temperature_K"] = 285.0
    code, _, err = run(capsys, "quantify", rec, "--surface", SURFACE, "--source", "16,22", "-q")
    assert code == EXIT_DATA and "physical band radiance" in one_line_error(err, "quantify")


def test_a_nan_result_exits_3_and_says_incomplete_in_its_files(capsys, rec, tmp_path, monkeypatch):
    """Whatever makes a rate NaN (the pipeline flags it: test_pipeline_trust),
    the command line never prints it with exit 0: the files are written and
    say "complete": false, and the exit status is 3."""
    import qogi.apps.cli
    import qogi.pipeline

    real = qogi.pipeline.quantify

    def nan_rate(*a, **k):
        res = real(*a, **k)
        r = res.surfaces[0].species["CH4"]
        r.mean_kg_h = float("nan")
        return res

    replace_everywhere(monkeypatch, real, nan_rate)
    out = tmp_path / "out.json"
    code, stdout, err = run(
        capsys,
        "quantify",
        rec,
        "--surface",
        SURFACE,
        "--source",
        "16,22",
        "--json",
        out,
        "--csv",
        tmp_path / "out.csv",
        "-q",
    )
    assert code == EXIT_DATA, err
    assert "cannot be trusted" in one_line_error(err, "quantify")
    d = json.loads(out.read_text())
    assert d["complete"] is False
    assert (tmp_path / "out.csv").exists()


# ----------------------------------------------------------------- everything


def test_every_command_documents_its_exit_codes(capsys):
    for cmd in (
        ["--help"],
        ["info", "--help"],
        ["quantify", "--help"],
        ["synth", "--help"],
        ["xsec", "--help"],
        ["demo", "--help"],
        ["gui", "--help"],
        ["hitran", "list", "--help"],
        ["hitran", "fetch", "--help"],
    ):
        code, out, _ = run(capsys, *cmd)
        text = " ".join(out.split())
        assert (
            code == 0
            and "exit status:" in text
            and "2 usage error" in text
            and "3 bad data" in text
        ), cmd


def test_an_internal_error_shows_the_traceback_and_asks_for_a_report(capsys, monkeypatch):
    import qogi.apps.info

    def broken(*a, **k):
        raise RuntimeError("an invariant broke")

    replace_everywhere(monkeypatch, qogi.apps.info.flir_info, broken)
    code, _, err = run(capsys, "info", "x.seq")
    assert code == EXIT_INTERNAL
    assert "Traceback" in err and "RuntimeError: an invariant broke" in err
    assert "this is a bug in qogi" in err and "report it" in err


def test_exit_codes_are_distinct():
    assert len({errors.EXIT_OK, EXIT_INTERNAL, EXIT_USAGE, EXIT_DATA, errors.EXIT_INTERRUPTED}) == 5


# ------------------------------------------------- issue 29: the last cases


def _lab_plume_image(h=240, w=320, src=(159.5, 227.0)):
    """A plume rising straight up from ``src`` and widening (a detection image)."""
    y, x = np.mgrid[0:h, 0:w].astype(float)
    rise = np.clip(src[1] - y, 0.0, None)
    width = 3.0 + 0.25 * rise
    return np.where(y <= src[1], np.exp(-0.5 * ((x - src[0]) / width) ** 2) / width, 0.0)


@pytest.mark.parametrize("dist", [-20.0, 0.0, float("nan")])
def test_auto_surfaces_refuse_a_distance_that_is_not_downstream(dist):
    """--auto-surfaces=-20 used to put the surface on the image's bottom row,
    below the source (0.107 kg/h for a 0.200 kg/h release, exit 0)."""
    from qogi.pipeline.surfaces import auto_surfaces

    with pytest.raises(ValueError, match=r"give distances > 0 px"):
        auto_surfaces(_lab_plume_image(), [dist], source=(159.5, 227.0))


@pytest.mark.parametrize("dist", [5000.0, 300.0, 228.0])
def test_auto_surfaces_refuse_a_distance_beyond_the_image_naming_the_largest(dist):
    """5000 px (or 300 on a 240-row image) used to be clipped to a stub in a
    corner or to the top row and read "not detected" without a word."""
    from qogi.pipeline.surfaces import auto_surfaces

    with pytest.raises(ValueError, match=r"the largest usable distance is 227 px"):
        auto_surfaces(_lab_plume_image(), [dist], source=(159.5, 227.0))
    assert auto_surfaces(_lab_plume_image(), [227.0], source=(159.5, 227.0))


def test_a_surface_cut_by_the_image_border_is_shortened_along_itself_and_warned():
    from qogi.diagnostics import Diagnostics
    from qogi.pipeline.surfaces import auto_surfaces

    img = _lab_plume_image(h=240, w=80, src=(39.5, 227.0))  # the plume outgrows the width
    warns = Diagnostics()
    low, high = auto_surfaces(img, [20.0, 200.0], source=(39.5, 227.0), warnings=warns)
    assert [w.surface for w in warns] == [high.name] and warns.codes() == ["surface-clipped"]
    assert "was cut to the image" in warns[0].message
    assert warns[0].data["length_px"] < warns[0].data["wanted_px"]
    p = np.asarray(high.points)
    assert np.all((p >= 0) & (p <= [79, 239]))
    assert p[0, 1] == pytest.approx(p[1, 1])  # still across the (vertical) axis
    assert np.asarray(low.points)[:, 0].min() > 0  # the low one fits: not warned


def test_a_surface_cut_at_the_border_of_an_oblique_plume_stays_inside_the_image():
    """The textured lab without its source: an end cut at the image's edge
    landed at x = -1.4e-14 and the run refused the surface (exit 2)."""
    from qogi.pipeline.surfaces import auto_surfaces

    h, w, src = 240, 320, (200.3, 200.7)
    y, x = np.mgrid[0:h, 0:w].astype(float)
    cut = 0
    for deg in np.arange(100.0, 170.0, 1.7):
        a = np.radians(deg)
        along = (x - src[0]) * np.cos(a) - (y - src[1]) * np.sin(a)
        across = (x - src[0]) * np.sin(a) + (y - src[1]) * np.cos(a)
        width = 3.0 + 0.4 * np.clip(along, 0.0, None)
        img = np.where(along >= 0, np.exp(-0.5 * (across / width) ** 2) / width, 0.0)
        for surf in auto_surfaces(img, [40.0, 80.0, 120.0, 160.0], source=src):
            p = np.asarray(surf.points)
            assert np.all((p >= 0) & (p <= [w - 1, h - 1])), (deg, surf.name, p.tolist())
            cut += int(np.any((p == 0) | (p == [w - 1, h - 1])))
    assert cut > 10  # the case at hand: ends on the border


@pytest.mark.parametrize(
    "value, needle",
    [("5000", "the largest usable distance is"), ("-20", "give distances > 0 px")],
)
def test_quantify_auto_surfaces_out_of_range_is_a_usage_error(capsys, rec, value, needle):
    code, _, err = run(capsys, "quantify", rec, f"--auto-surfaces={value}", "--source", "16,22")
    line = one_line_error(err, "quantify")
    assert code == EXIT_USAGE and f"--auto-surfaces {value}" in line and needle in line


def test_quantify_accepts_a_dict_config_and_names_the_types_it_accepts(rec):
    """quantify(rec, surfaces, {"species": ["CH4"]}) and (..., "CH4") used
    to fail with AttributeError: 'dict' object has no attribute 'source'."""
    import qogi

    surfaces = [qogi.Surface.parse(SURFACE)]
    with pytest.raises(TypeError, match=r"config must be a qogi\.QuantifyConfig, a dict"):
        qogi.quantify(str(rec), surfaces, "CH4")
    with pytest.raises(errors.UsageError, match=r"unknown setting.*specie\b"):
        qogi.quantify(str(rec), surfaces, {"specie": ["CH4"]})
    got = qogi.quantify(
        str(rec), surfaces, {"species": ["CH4"], "source": [16, 22], "frames": [0, 6]}
    )
    assert got.config == qogi.QuantifyConfig(species=["CH4"], source=(16, 22), frames=(0, 6))


@pytest.mark.parametrize(
    "field, value",
    [
        ("num_threads", 1.5),
        ("num_threads", "2"),
        ("num_threads", -1),
        ("num_threads", True),
        ("pair_stride", 2.0),
        ("block_frames", 64.5),
        ("frames", (0.5, 10)),
        ("frames", (0, 10.0)),
    ],
)
def test_integer_settings_refuse_other_values_at_construction(field, value):
    """QuantifyConfig(num_threads=1.5) used to be accepted and fail later
    with a TypeError inside the engine."""
    import qogi

    with pytest.raises(ValueError, match=f"{field} must be"):
        qogi.QuantifyConfig(**{field: value})


def test_integer_settings_take_numpy_integers_as_ints():
    import qogi

    cfg = qogi.QuantifyConfig(num_threads=np.int64(2), frames=(np.int32(0), np.int64(5)))
    assert cfg.num_threads == 2 and type(cfg.num_threads) is int
    assert cfg.frames == (0, 5) and all(type(v) is int for v in cfg.frames)


BROKEN_PAR = "  61 3000.000000 1.000E-20 this is not a HITRAN record\n"  # 53 characters


def test_a_line_list_not_in_the_par_format_is_bad_data_naming_file_and_line(
    capsys, tmp_path, monkeypatch
):
    """Given with --line-list or found on QOGI_HITRAN_PATH (xsec, hitran
    list, quantify): exit 3 naming the file, the line and what the format
    needs, not an internal error (RuntimeError: truncated record, exit 1)."""
    folder = tmp_path / "lines"
    folder.mkdir()
    par = folder / "CH4.par"
    par.write_text("\n" + BROKEN_PAR)  # the record is line 2
    monkeypatch.setenv("QOGI_CACHE_DIR", str(tmp_path / "cache"))
    code, _, err = run(capsys, "xsec", "CH4", "--range", "2990", "3010", "--line-list", par)
    line = one_line_error(err, "xsec")
    assert code == EXIT_DATA and f"{par}:2: truncated record" in line
    assert "one 160-character record per line" in line
    monkeypatch.setenv("QOGI_HITRAN_PATH", str(folder))
    code, _, err = run(capsys, "hitran", "list", "CH4")
    assert code == EXIT_DATA and f"{par}:2" in one_line_error(err, "hitran list")
    # quantify in a fresh process (this one may hold the scene's tables already).
    rec = small_recording(tmp_path / "r.h5", n_frames=8)
    r = subprocess.run(
        [sys.executable, "-m", "qogi", "quantify", str(rec), "-q", "--surface", SURFACE],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert r.returncode == EXIT_DATA and f"{par}:2" in one_line_error(r.stderr, "quantify")


@pytest.mark.parametrize("source", [[], ["--source", "16,22"]])
def test_a_texture_velocimetry_is_warned_with_or_without_a_source(capsys, rec, tmp_path, source):
    """--velocity farneback without --source read 0.0001 kg/h for a 0.2 kg/h
    release without a word; with --source the engine refused it ("source_mask
    applies to the fluid method only"). Both now run and say why the number
    is not a flux."""
    out = tmp_path / "r.json"
    code, _, err = run(
        capsys, "quantify", rec, "--surface", SURFACE, "--velocity", "farneback", *source,
        "-q", "--json", out,
    )  # fmt: skip
    assert code in (0, EXIT_DATA) and "Traceback" not in err and "source_mask" not in err, err
    [w] = [w for w in json.loads(out.read_text())["warnings"] if w["code"] == "velocity-texture"]
    assert "tracks the plume's texture" in w["message"] and "fluid" in w["message"]


def test_the_velocity_map_is_blank_where_no_flow_was_computed(tmp_path):
    """The maps plot painted 0 px/frame outside the flow's part of the
    region (the upper half of the demo's plume); there is no velocity there."""
    import matplotlib

    matplotlib.use("Agg")
    import qogi

    chs = [qogi.SpectralResponse([2941.18, 3125.0], [1.0, 1.0], name="3.2-3.4 um")]
    t = np.arange(12)[:, None, None]
    y, x = np.arange(96)[None, :, None], np.arange(48)[None, None, :]
    temp = 285.0 + 25.0 * np.exp(-((x - 24) ** 2 + (y - (88 - 2 * t)) ** 2) / 20.0)
    frames = chs[0].band_radiance(temp.ravel()).reshape(temp.shape)[:, None]
    tall = qogi.Recording.from_arrays(
        frames,
        quantity="radiance",
        camera=qogi.Camera("test camera", 1e-3, chs, frame_rate_hz=10.0, netd_K=0.02),
        scene=qogi.Scene(distance_m=3.0, ambient_temperature_K=288.0, pressure_Pa=101325.0),
    )
    cfg = qogi.QuantifyConfig(source=(24.0, 90.0))
    res = qogi.quantify(tall, [qogi.Surface.parse("8,80,40,80")], cfg, keep_maps=True)
    m = res.maps(res.map_frames[0])
    u, v = m["velocity_px_per_frame"]
    x0, y0, x1, y1 = m["velocity_region"]
    inside = np.zeros(u.shape, bool)
    inside[y0:y1, x0:x1] = True
    assert not inside.all(), "the flow covers the whole region: nothing to check"
    assert np.isnan(u[~inside]).all() and np.isnan(v[~inside]).all()
    assert np.isfinite(u[inside]).all() and np.isfinite(v[inside]).all()
    fig = res.plot(tmp_path / "maps.png", kind="maps")
    [ax] = [a for a in fig.axes if a.get_title().startswith("velocity")]
    assert "where the flow was computed" in ax.get_title()
    assert len(ax.patches) == 1  # the computed region's outline


def test_a_pair_stride_too_long_for_the_frames_is_reduced_with_a_warning(rec):
    """Another option that was clamped without a word: pair_stride=10 on
    8 frames ran with a stride of 3."""
    import qogi

    cfg = qogi.QuantifyConfig(source=(16.0, 22.0), pair_stride=10)
    res = qogi.quantify(str(rec), [qogi.Surface.parse(SURFACE)], cfg)
    [w] = [w for w in res.warnings if w.code == "pair-stride-reduced"]
    assert w.data == {"given": 10, "used": 3} and "was reduced to 3" in w.message
