"""The viewer opens camera files directly: it asks for the scene facts a file
does not hold in a small form instead of failing, remembers them per file,
refuses a camera whose band is not the file's, and quantifies a FLIR .seq of a
synthetic release to the same rate as the release's HDF5 recording."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import AMBIENT_K, H, W, make_recording

from qogi.io.flir_writer import write_recording_as_seq
from qogi.io.telops import write_hcc
from qogi_gui.store import UserStore
from qogi_gui.viewmodel import ViewModel


def _run_to_end(vm, timeout=60.0):
    assert vm.job.wait(timeout)
    assert vm.poll()


@pytest.fixture
def seq_and_h5(tmp_path):
    """The conftest's warm-blob recording, one channel (3.2-3.4 um), as HDF5
    and as a FLIR .seq written by qogi's writer (object distance: FLIR's
    default 1 m; the scene's is 3 m)."""
    rec = make_recording(n_channels=1, truth_kg_s=1e-3)
    h5 = tmp_path / "blob.h5"
    rec.save(h5)
    seq = tmp_path / "blob.seq"
    write_recording_as_seq(rec, seq, object_distance_m=1.0)
    return seq, h5


def test_a_camera_file_asks_for_its_scene_facts_then_opens_and_remembers_them(tmp_path, seq_and_h5):
    seq, _ = seq_and_h5
    store = UserStore(tmp_path / "config")
    vm = ViewModel(store=store)
    assert not vm.open(seq)
    req = vm.scene_request
    assert req is not None and req.needs == ["camera"]
    assert "distance_m" in req.defaults and "factory default" in req.hint("distance_m")
    assert "give the scene facts it does not hold (camera)" in vm.last_message.text
    # A bad entry is named, and the form stays.
    assert not vm.submit_scene({"camera": "", "distance_m": "-2"})
    assert "give the camera" in req.errors["camera"] and "distance" in req.errors["distance_m"]
    assert vm.recording is None and vm.scene_request is req
    # Filled in: it opens, shows the flagged pressure, and remembers the facts.
    assert vm.submit_scene({"camera": "gf320", "distance_m": "3", "ambient_temperature_K": ""})
    assert vm.scene_request is None and vm.recording is not None
    assert vm.recording.scene.distance_m == 3.0
    assert vm.recording.scene_origin["distance_m"] == "given"
    assert any("scene-pressure-assumed" in m.text for m in vm.messages)
    vm.close()
    again = ViewModel(store=UserStore(tmp_path / "config"))
    assert again.open(seq) and again.scene_request is None
    assert again.recording.scene.distance_m == 3.0
    again.close()


def test_a_telops_file_needs_distance_and_ambient_in_the_form(tmp_path):
    frames = [np.full((H, W), 300.0 + k) for k in range(4)]
    p = tmp_path / "wheel.hcc"
    write_hcc(p, frames, [1.7e9 + 0.0025 * k for k in range(4)], fw_positions=[0, 1, 2, 3])
    vm = ViewModel(store=UserStore(tmp_path / "config"))
    assert not vm.open(p)
    assert vm.scene_request.needs == ["camera", "distance_m", "ambient_temperature_K"]
    assert not vm.submit_scene({"camera": "fast-m150", "distance_m": "5"})
    assert "give the ambient temperature" in vm.scene_request.errors["ambient_temperature_K"]
    assert vm.submit_scene({"ambient_temperature_K": "290"})
    assert vm.recording.shape == (1, 4, H, W)
    vm.close()


def test_the_viewer_refuses_the_lwir_sample_through_a_gas_camera(tmp_path, shared_dir):
    sample = shared_dir / "samples" / "flir" / "SampleCSQ.csq"
    if not sample.is_file():
        pytest.skip(f"FLIR sample not found: {sample}")
    vm = ViewModel(store=UserStore(tmp_path / "config"))
    assert not vm.open(sample)
    assert not vm.submit_scene({"camera": "gf320", "distance_m": "3"})
    assert vm.recording is None and vm.scene_request is not None
    assert "9.5 um" in vm.scene_request.error and "3.20-3.40 um" in vm.scene_request.error
    assert "9.5 um" in vm.last_message.text
    # Nothing wrong was remembered.
    assert vm.store.scene_for(sample) is None


def test_quantifying_the_seq_in_the_viewer_reads_the_hdf5_rate(tmp_path, seq_and_h5):
    seq, h5 = seq_and_h5
    rates = []
    for path, facts in (
        (h5, None),
        (seq, {"camera": "gf320", "distance_m": "3", "ambient_temperature_K": str(AMBIENT_K)}),
    ):
        vm = ViewModel(store=UserStore(tmp_path / f"config-{path.suffix}"))
        if facts is None:
            assert vm.open(path)
        else:
            assert not vm.open(path) and vm.submit_scene(facts)
        vm.add_surface([(4, 12), (28, 12)], name="A")
        bad = vm.update_settings(velocity="exit", exit_velocity_m_s="0.5")
        assert not any(bad.values()), bad
        assert vm.start_run(), vm.last_message.text
        _run_to_end(vm)
        assert vm.result is not None, vm.last_message.text
        rates.append(vm.result.surfaces[0].species["CH4"].mean_kg_h)
        if facts is not None:
            assert "scene-pressure-assumed" in vm.result.warnings.codes()
        vm.close()
    print(f"viewer: HDF5 {rates[0]:.5g} kg/h, FLIR .seq {rates[1]:.5g} kg/h")
    assert rates[0] != 0 and rates[1] == pytest.approx(rates[0], rel=0.01)
