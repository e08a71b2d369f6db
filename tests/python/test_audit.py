"""A record that stands up in an audit (issue 28, item 5): the result names
the file it measured by its SHA-256, the recording's and the run's UTC
times, the qogi that ran, and the site, component, operator and location
given; the JSON, the summary CSV, the tables and the batch summary carry
them."""

from __future__ import annotations

import csv
import dataclasses
import datetime
import hashlib
import json

import numpy as np
import pytest

import qogi
from qogi.apps import batch
from qogi.audit import AUDIT_FIELDS, RECORD_SETTINGS, utc_text
from qogi.pipeline import QuantifyConfig, quantify
from qogi.pipeline.surfaces import Surface

SURFACE = Surface([(10, 20), (50, 20)], name="S1")
#: 2026-11-28 05:32:36.125 UTC, a capture time as a FLIR or Telops header gives it.
START_S = 1795843956.125


def _recording(path, start_s=START_S):
    """A tiny scene (a static CH4 band over a plate, NETD noise, 6 frames)
    saved to ``path`` with the capture time its camera file would give."""
    from qogi.io.recording import Recording, Scene
    from qogi.physics.forward import forward_model
    from qogi.physics.radiometry import radiance_to_temperature

    cam = dataclasses.replace(qogi.camera_preset("gf320"), width=60, height=40)
    model = forward_model(cam.channels, ["CH4"])
    x = np.arange(cam.width)
    frac = 5e-4 * np.exp(-0.5 * ((x - 30) / 4.0) ** 2)
    L = model.band_radiance(frac[:, None], 295.0, 0.02, 295.0, 280.0)[:, 0]
    t_img = radiance_to_temperature(L[None, None, None, :], cam.channels)[0, 0, 0]
    rng = np.random.default_rng(0)
    stack = np.broadcast_to(t_img, (6, 1, cam.height, cam.width)) + rng.normal(
        0.0, cam.netd_K, (6, 1, cam.height, cam.width)
    )
    scene = Scene(distance_m=3.0, ambient_temperature_K=295.0, pressure_Pa=101325.0)
    rec = Recording.from_arrays(stack, quantity="radiometric_temperature", camera=cam, scene=scene)
    if start_s is not None:
        rec.attrs["start_time_posix_s"] = start_s
    rec.save(path)
    return path


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    p = _recording(tmp_path_factory.mktemp("audit") / "valve.h5")
    cfg = QuantifyConfig(
        species=["CH4"],
        velocity="wind",
        wind_speed_m_s=1.0,
        site="Compressor station 7",
        component="valve V-102",
        operator="J. Doe",
        location="52.1234 N, 4.5678 E",
    )
    before = datetime.datetime.now(datetime.timezone.utc)
    res = quantify(qogi.open_recording(p), [SURFACE], cfg)
    after = datetime.datetime.now(datetime.timezone.utc)
    return p, res, before, after


def _parse(text):
    assert text.endswith("Z"), text
    return datetime.datetime.fromisoformat(text[:-1] + "+00:00")


def test_the_result_names_its_file_times_version_and_who_measured(run):
    p, res, before, after = run
    a = res.audit
    assert list(a) == list(AUDIT_FIELDS) + list(RECORD_SETTINGS)
    assert a["recording_sha256"] == hashlib.sha256(p.read_bytes()).hexdigest()
    assert a["recording_time_utc"] == "2026-11-28T05:32:36.125Z"
    started, finished = _parse(a["run_started_utc"]), _parse(a["run_finished_utc"])
    # Millisecond resolution: the stamps lie within the call, start before end.
    slack = datetime.timedelta(milliseconds=1)
    assert before - slack <= started <= finished <= after + slack
    assert a["qogi_version"] == qogi.__version__
    assert (a["site"], a["component"], a["operator"], a["location"]) == (
        "Compressor station 7",
        "valve V-102",
        "J. Doe",
        "52.1234 N, 4.5678 E",
    )


def test_the_json_summary_csv_and_tables_carry_the_record(run, tmp_path):
    _, res, _, _ = run
    d = json.loads(res.to_json())
    assert d["audit"] == res.audit
    # The record settings are settings too: a replay (--config result.json) keeps them.
    assert QuantifyConfig.from_dict(d["config"]).operator == "J. Doe"
    res.to_csv(tmp_path / "out.csv")
    with open(tmp_path / "out.summary.csv", newline="") as fh:
        [row] = list(csv.DictReader(fh))
    for k, v in res.audit.items():
        assert row[k] == v, k
    # the operating point beside it: where in the envelope, and the PoD there
    op = res.surfaces[0].species["CH4"].operating_point
    assert float(row["distance_m"]) == pytest.approx(3.0) == op["distance_m"]
    assert (
        float(row["speed_m_s"]) == pytest.approx(op["speed_m_s"], rel=1e-4) and op["speed_m_s"] > 0
    )
    assert (
        float(row["pod_90_kg_h"]) == pytest.approx(op["pod_90_kg_h"], rel=1e-4)
        and op["pod_90_kg_h"] > 0
    )
    pytest.importorskip("pandas")
    df = res.to_dataframe(summary=True)
    assert df.loc[0, "site"] == "Compressor station 7"
    assert df.attrs["recording_sha256"] == res.audit["recording_sha256"]


def test_unknown_facts_stay_unknown_rather_than_made_up(tmp_path):
    # In memory: no file to hash; a file without a capture time: none stated.
    p = _recording(tmp_path / "plain.h5", start_s=None)
    rec = qogi.open_recording(p)
    cfg = QuantifyConfig(species=["CH4"], velocity="wind", wind_speed_m_s=1.0)
    a = quantify(rec, [SURFACE], cfg).audit
    assert a["recording_time_utc"] is None and a["recording_sha256"] is not None
    assert all(a[k] is None for k in RECORD_SETTINGS)
    mem = qogi.Recording.from_arrays(
        rec.frames(0, rec.n_frames), quantity=rec.quantity, camera=rec.camera, scene=rec.scene
    )
    assert quantify(mem, [SURFACE], cfg).audit["recording_sha256"] is None


def test_utc_text_is_iso_8601_in_utc_and_refuses_nothing_it_cannot_read():
    assert utc_text(0.0) == "1970-01-01T00:00:00.000Z"
    assert utc_text(None) is None and utc_text(float("nan")) is None and utc_text("x") is None


def test_the_batch_summary_has_the_record_columns(run):
    _, res, _, _ = run
    d = res.to_dict()
    d["batch"] = {"name": "valve", "path": "valve.h5"}
    row = batch.summary_row(d)
    for k in batch._AUDIT_COLUMNS:
        assert row[k] == res.audit[k], k
    key = f"{res.surfaces[0].surface.name}/CH4"
    op = res.surfaces[0].species["CH4"].operating_point
    assert row[f"{key} pod_90_kg_h"] == pytest.approx(op["pod_90_kg_h"])
    pytest.importorskip("pandas")
    df = batch.summary_frame([row, batch.failed_row({"name": "x", "path": "x.h5"})])
    assert df.loc[0, "operator"] == "J. Doe" and df.loc[1, "operator"] == ""
