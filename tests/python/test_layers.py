"""The package by layer (docs/architecture.md): base < physics < measure < io
< synth < pipeline < apps < public. A module imports only its own layer and
the ones below, the import graph has no cycle, an import inside a function is
the exception with its reason beside it, the documented API is where users
import it, and the docs' picture of the layers is the code's."""

from __future__ import annotations

import ast
import importlib
import importlib.util
import pathlib
import re
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("import_graph", ROOT / "scripts" / "import_graph.py")
assert _spec is not None and _spec.loader is not None
graph = importlib.util.module_from_spec(_spec)
sys.modules["import_graph"] = graph  # its dataclasses look themselves up there
_spec.loader.exec_module(graph)

#: The function-local imports that are allowed, and why (each also says so in
#: a comment on its line or the line before it).
DEFERRED = {
    # `import qogi.apps.cli` loads no numpy or engine: a Ctrl-C while the
    # commands' modules load is then main()'s "interrupted" (test_interrupt).
    "qogi.apps.cli": "start-up",
    # The console script's entry imports the command line inside its guard,
    # so that a Ctrl-C while argparse and the rest load is exit 130.
    "qogi.apps.console": "start-up",
    # qogi batch needs the optional Dask, pandas and pyarrow (qogi[batch]).
    "qogi.apps._cli_batch": "optional",
    # qogi envelope quantifies through qogi batch: the same optional packages.
    "qogi.apps._cli_envelope": "optional",
}


@pytest.fixture(scope="module")
def edges():
    return graph.edges()


def test_every_module_has_a_layer():
    root = {m for m in graph.modules() if m.count(".") == 1 or m == "qogi"}
    base = {m for m in root if graph.layer_of(m) == "base"}
    # A new root module is base (no qogi import above the base) or public:
    # it must be placed knowingly, not by default.
    assert base == {
        "qogi._interrupts",
        "qogi._progress",
        "qogi._version",
        "qogi.audit",
        "qogi.cache",
        "qogi.contract",
        "qogi.diagnostics",
        "qogi.errors",
        "qogi.files",
        "qogi.hdf5_files",
        "qogi.progress",
        "qogi.tables",
        "qogi.units",
        "qogi.workers",
    }


def test_no_layer_imports_a_higher_one(edges):
    bad = [
        f"{e.source} ({graph.layer_of(e.source)}) imports {e.target} "
        f"({graph.layer_of(e.target)}) at line {e.line}"
        for e in graph.upward(edges)
    ]
    assert bad == []


def test_the_import_graph_has_no_cycle(edges):
    assert graph.cycles(edges) == []


def test_imports_inside_functions_are_only_the_deferred_ones_with_their_reason(edges):
    local = sorted({e.source for e in edges if e.local})
    assert local == sorted(DEFERRED)
    for e in edges:
        if not e.local:
            continue
        lines = graph.modules()[e.source].read_text().splitlines()
        # The comment sits on the import's line, its first line, or just above.
        nearby = " ".join(lines[max(0, e.line - 5) : e.line])
        assert "#" in nearby, f"{e.source}:{e.line}: a deferred import without its reason"


def test_the_checker_sees_a_back_edge_a_cycle_and_a_local_import(tmp_path):
    pkg = tmp_path / "qogi"
    (pkg / "physics").mkdir(parents=True)
    (pkg / "pipeline").mkdir()
    for d in (pkg, pkg / "physics", pkg / "pipeline"):
        (d / "__init__.py").write_text("")
    (pkg / "physics" / "optics.py").write_text(
        "def f():\n    from ..pipeline.run import quantify\n"
    )
    (pkg / "pipeline" / "run.py").write_text("from .state import S\nquantify = 1\n")
    (pkg / "pipeline" / "state.py").write_text("from .run import quantify\nS = 1\n")
    found = graph.edges(pkg)
    assert [(e.source, e.target) for e in graph.upward(found)] == [
        ("qogi.physics.optics", "qogi.pipeline.run")
    ]
    assert [e.local for e in found if e.source == "qogi.physics.optics"] == [True]
    assert graph.cycles(found) == [["qogi.pipeline.run", "qogi.pipeline.state"]]


def test_the_docs_picture_of_the_layers_is_the_codes():
    text = (ROOT / "docs" / "architecture.md").read_text()
    assert graph.doc_block(text) == graph.mermaid(), (
        "docs/architecture.md is stale: run python scripts/import_graph.py --write"
    )


# --------------------------------------------------------------- the documented API


def _documented_imports():
    """Every ``from qogi.X import a, b`` and ``import qogi.X`` in the README
    and docs, as (module, names)."""
    found = []
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]:
        for block in re.findall(r"```(?:python|py)?\n(.*?)```", path.read_text(), re.S):
            try:
                tree = ast.parse(block)
            except SyntaxError:
                continue
            for node in ast.walk(tree):
                if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("qogi"):
                    found.append((node.module, tuple(a.name for a in node.names), path.name))
                elif isinstance(node, ast.Import):
                    found += [
                        (a.name, (), path.name) for a in node.names if a.name.startswith("qogi")
                    ]
    return found


def test_every_import_the_docs_show_works():
    docs = _documented_imports()
    assert len(docs) >= 10, "the docs' code blocks were not found"
    for module, names, where in docs:
        m = importlib.import_module(module)
        for n in names:
            assert hasattr(m, n) or importlib.util.find_spec(f"{module}.{n}"), (
                f"{where}: from {module} import {n}"
            )


#: Where users import qogi today (README, docs, the package's own list): the
#: paths and names that must not move.
PUBLIC_PATHS = {
    "qogi": [
        "quantify",
        "QuantifyConfig",
        "open_recording",
        "Recording",
        "Camera",
        "Scene",
        "Truth",
        "RecordingError",
        "RecordingWriter",
        "write_recording",
        "Result",
        "Surface",
        "Region",
        "auto_surfaces",
        "detect_source",
        "plume_image",
        "camera_preset",
        "forward_model",
        "cross_section",
        "optical_flow",
        "pod",
        "Cancelled",
        "__version__",
    ],
    "qogi.camera": [
        "Calibration",
        "CalibrationScene",
        "fit_calibration",
        "camera_optics",
        "warm_optics_radiance",
        "add_warm_optics",
        "correct_warm_optics",
        "add_netd_noise",
        "Camera",
    ],
    "qogi.inversion": [
        "Inversion",
        "fixed",
        "free",
        "prior",
        "tied",
        "scene_table",
        "invert_on_mixing_line",
        "plume_depth_from_width",
    ],
    "qogi.radiometry": ["band_table", "temperature_to_radiance", "radiance_to_temperature"],
    "qogi.batch": ["run"],
    "qogi.velocimetry": ["FlowEstimator", "optical_flow", "optical_flow_sequence"],
    "qogi.synth": ["simulate_preset", "preset", "Release", "Simulation", "mean_flow"],
    "qogi.io": [
        "read_flir",
        "read_flir_recording",
        "read_numpy",
        "read_tiff",
        "read_recording",
        "open_hcc",
        "write_flir_seq",
        "write_hcc",
    ],
    "qogi.units": ["parse_unit"],
    "qogi.errors": ["UsageError", "DataError", "QogiError"],
}


@pytest.mark.parametrize("module", sorted(PUBLIC_PATHS))
def test_the_public_names_stay_where_users_import_them(module):
    m = importlib.import_module(module)
    missing = [n for n in PUBLIC_PATHS[module] if not hasattr(m, n)]
    assert missing == []


def test_a_documented_path_is_its_layers_module_not_a_copy():
    import qogi.camera
    import qogi.inversion
    import qogi.measure.inversion
    import qogi.physics.camera

    assert qogi.camera.fit_calibration is qogi.physics.camera.fit_calibration
    assert qogi.inversion.fixed is qogi.measure.inversion.fixed
    assert qogi.Camera is qogi.physics.camera.Camera
    assert set(qogi.camera.__all__) == set(qogi.physics.camera.__all__)
    for facade, home in [
        ("qogi.camera", "qogi.physics.camera"),
        ("qogi.radiometry", "qogi.physics.radiometry"),
        ("qogi.inversion", "qogi.measure.inversion"),
        ("qogi.velocimetry", "qogi.measure.velocimetry"),
        ("qogi.batch", "qogi.apps.batch"),
        ("qogi.synth", "qogi.synth.plume"),
    ]:
        a, b = importlib.import_module(facade), importlib.import_module(home)
        assert all(getattr(a, n) is getattr(b, n) for n in b.__all__), facade
