"""The pipeline reads as a chain: recording -> background -> columns ->
velocity -> flux -> budget, each stage importing only the stages (and the
pipeline's helpers, config, sampling and state modules) before it. Parsed from the source (ast),
so a back-edge inside a function body counts too."""

from __future__ import annotations

import ast
import pathlib

import qogi.pipeline

PACKAGE = pathlib.Path(qogi.pipeline.__file__).parent
#: The pipeline's own helpers (what only the stages use), then the stages in
#: data-flow order; a module may import only those before it.
ORDER = [
    "surfaces",
    "settings",
    "config_io",
    "detection",
    "checks",
    "selfchecks",
    "timebase",
    "flux_summary",
    "budget_terms",
    "hotgas",
    "background_choice",
    "error_model",
    "result",
    "config",
    "sampling",
    "state",
    "setup",
    "align",
    "background",
    "columns",
    "velocity",
    "flux",
    "budget",
    "run",
    "__init__",
]


def imported_stages(path: pathlib.Path) -> set:
    """The package's modules that ``path`` imports (relative or absolute)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom):
            if node.level == 1:  # from .x import ... / from . import x
                if node.module:
                    found.add(node.module.split(".")[0])
                else:
                    found.update(a.name for a in node.names)
            elif node.level == 0 and node.module and node.module.startswith("qogi.pipeline."):
                found.add(node.module.split(".")[2])
            elif node.level == 0 and node.module == "qogi.pipeline":
                found.add("__init__")
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("qogi.pipeline"):
                    parts = a.name.split(".")
                    found.add(parts[2] if len(parts) > 2 else "__init__")
    return found


def test_every_pipeline_module_has_a_place_in_the_chain():
    modules = {p.stem for p in PACKAGE.glob("*.py")}
    assert modules == set(ORDER), f"place new modules in ORDER: {sorted(modules ^ set(ORDER))}"


def test_no_stage_imports_a_later_stage():
    back_edges = []
    for name in ORDER:
        rank = ORDER.index(name)
        for target in imported_stages(PACKAGE / f"{name}.py"):
            if target not in ORDER:
                back_edges.append(f"{name} imports unknown module {target}")
            elif ORDER.index(target) >= rank:
                back_edges.append(f"{name} imports {target}")
    assert back_edges == []


def test_the_checker_sees_a_back_edge(tmp_path):
    p = tmp_path / "m.py"
    p.write_text("def f():\n    from .flux import block_flux\n    import qogi.pipeline.budget\n")
    assert imported_stages(p) == {"flux", "budget"}
