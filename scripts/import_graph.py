"""The Python package's import graph, read from the source, and its layers.

``python scripts/import_graph.py`` prints the Mermaid picture of the layers
that docs/architecture.md holds (``--check`` exits 1 when the docs are stale;
tests/python/test_layers.py checks it in ``make test``). The same functions
back the layering test: a module imports only its own layer and the layers
below it, the graph has no cycle, and a function-local import is the
exception, with its reason beside it.

Parsed with ``ast`` (nothing is imported): an import inside a function body
counts like any other; one under ``if TYPE_CHECKING:`` does not (it never
runs).
"""

from __future__ import annotations

import argparse
import ast
import collections
import pathlib
import sys
from dataclasses import dataclass
from typing import Dict, List, Optional, Set, Tuple

ROOT = pathlib.Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "python" / "qogi"
DOC = ROOT / "docs" / "architecture.md"

#: The layers, lowest first: a module may import its own layer and those below.
LAYERS = ["base", "physics", "measure", "io", "synth", "pipeline", "apps", "public"]
#: What each layer is for (the picture's labels).
ROLES = {
    "base": "errors, files, units, progress, the recording contract, HDF5 safety",
    "physics": "spectra, optics, radiometry, forward model, camera and presets",
    "measure": "per-pixel inversion, mixing line, velocimetry, flux integral",
    "io": "the recording model, each reader and writer, open_recording",
    "synth": "synthetic releases, backgrounds, the synthetic camera",
    "pipeline": "the quantification: settings, stages, checks, result",
    "apps": "command line, batch on Dask, reports, probability of detection",
    "public": "the package's names (import qogi) and the documented paths",
}
#: Root modules that are the public face, not the base: the package itself,
#: ``python -m qogi`` and the documented paths kept for users
#: (``from qogi.camera import ...``), each re-exporting its layer's module.
PUBLIC = {
    "qogi",
    "qogi.__main__",
    "qogi.batch",
    "qogi.camera",
    "qogi.inversion",
    "qogi.radiometry",
    "qogi.velocimetry",
}
#: The extension module (no source to parse): the base of every layer.
ENGINE = "qogi._engine"


@dataclass(frozen=True)
class Edge:
    """``source`` imports ``target`` at ``line``; ``local``: inside a function."""

    source: str
    target: str
    line: int
    local: bool


def modules(package: pathlib.Path = PACKAGE) -> Dict[str, pathlib.Path]:
    """Dotted name -> file of every module of the package."""
    out = {}
    for p in sorted(package.rglob("*.py")):
        parts = list(p.relative_to(package.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


def layer_of(module: str) -> str:
    """The layer of a dotted module name (its folder; root modules are the base)."""
    if module in PUBLIC:
        return "public"
    parts = module.split(".")
    if len(parts) >= 2 and parts[1] in LAYERS:
        return parts[1]
    return "base"


def _is_type_checking(node: ast.AST) -> bool:
    return isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)


def edges(package: pathlib.Path = PACKAGE) -> List[Edge]:
    """Every import of a package module by another (function-local ones too,
    ``TYPE_CHECKING`` ones not)."""
    mods = modules(package)
    known = set(mods) | {ENGINE}
    out: List[Edge] = []
    for name, path in mods.items():
        pkg = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]

        def visit(node: ast.AST, local: bool, name=name, pkg=pkg) -> None:
            for child in ast.iter_child_nodes(node):
                if _is_type_checking(child):
                    continue
                inner = local or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef))
                targets: List[str] = []
                if isinstance(child, ast.ImportFrom):
                    if child.level:
                        base = pkg.split(".")
                        base = base[: len(base) - (child.level - 1)]
                        module = ".".join(base + ([child.module] if child.module else []))
                    else:
                        module = child.module or ""
                    for alias in child.names:
                        full = f"{module}.{alias.name}"
                        targets.append(full if full in known else module)
                elif isinstance(child, ast.Import):
                    targets = [a.name for a in child.names]
                for t in targets:
                    if t in known and t != name:
                        out.append(Edge(name, t, child.lineno, local))
                visit(child, inner)

        visit(ast.parse(path.read_text(encoding="utf-8"), str(path)), False)
    return out


def upward(found: List[Edge]) -> List[Edge]:
    """The imports of a higher layer by a lower one."""
    rank = {k: i for i, k in enumerate(LAYERS)}
    return [
        e
        for e in found
        if e.target != ENGINE and rank[layer_of(e.target)] > rank[layer_of(e.source)]
    ]


def cycles(found: List[Edge]) -> List[List[str]]:
    """Strongly connected groups of more than one module (Tarjan)."""
    graph: Dict[str, Set[str]] = collections.defaultdict(set)
    for e in found:
        graph[e.source].add(e.target)
    index: Dict[str, int] = {}
    low: Dict[str, int] = {}
    stack: List[str] = []
    on: Set[str] = set()
    groups: List[List[str]] = []

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                groups.append(sorted(group))

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10000))
    try:
        for v in sorted(graph):
            if v not in index:
                strong(v)
    finally:
        sys.setrecursionlimit(limit)
    return groups


def mermaid(package: pathlib.Path = PACKAGE) -> str:
    """The layers as a Mermaid flowchart: one box per layer listing its
    modules, one arrow per pair of layers where one imports from the other,
    the engine at the bottom. (No counts on the arrows: the picture changes
    when the structure does, not with every import.)"""
    mods = modules(package)
    found = edges(package)
    by_layer: Dict[str, List[str]] = collections.defaultdict(list)
    for m in mods:
        by_layer[layer_of(m)].append(m)
    counts: Dict[Tuple[str, str], int] = collections.Counter()
    to_engine: Dict[str, int] = collections.Counter()
    for e in found:
        a = layer_of(e.source)
        if e.target == ENGINE:
            to_engine[a] += 1
            continue
        b = layer_of(e.target)
        if a != b:
            counts[(a, b)] += 1
    lines = ["```mermaid", "flowchart TB"]
    for layer in reversed(LAYERS):
        names = sorted(m.split(".", 1)[1] if "." in m else m for m in by_layer[layer])
        shown = ", ".join(n.removeprefix(layer + ".") for n in names)
        lines.append(f'  {layer}["<b>{layer}</b>: {ROLES[layer]}<br/><small>{shown}</small>"]')
    lines.append('  engine[("qogi._engine (C++: cpp/engine)")]')
    for (a, b), _n in sorted(counts.items(), key=lambda kv: (LAYERS.index(kv[0][0]), kv[0][1])):
        lines.append(f"  {a} --> {b}")
    for a, _n in sorted(to_engine.items(), key=lambda kv: LAYERS.index(kv[0])):
        lines.append(f"  {a} -.-> engine")
    lines.append("```")
    return "\n".join(lines) + "\n"


BEGIN = "<!-- import-graph: begin (scripts/import_graph.py writes this block) -->\n"
END = "<!-- import-graph: end -->\n"


def doc_block(text: str) -> Optional[str]:
    """The generated block of docs/architecture.md, or None."""
    if BEGIN not in text or END not in text:
        return None
    return text.split(BEGIN, 1)[1].split(END, 1)[0]


def main(argv: Optional[List[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="rewrite docs/architecture.md's block")
    ap.add_argument("--check", action="store_true", help="exit 1 when the docs' block is stale")
    args = ap.parse_args(argv)
    picture = mermaid()
    if not (args.write or args.check):
        sys.stdout.write(picture)
        return 0
    text = DOC.read_text(encoding="utf-8")
    old = doc_block(text)
    if old is None:
        print(f"{DOC}: no import-graph block (add {BEGIN.strip()} ... {END.strip()})")
        return 1
    if args.check:
        if old != picture:
            print(f"{DOC} is stale: run python scripts/import_graph.py --write")
            return 1
        return 0
    DOC.write_text(text.replace(BEGIN + old + END, BEGIN + picture + END), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
