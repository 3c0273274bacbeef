"""The layout pinned: the layering of the packages, no import circle, modules and folders of
a size a newcomer can read, and no reference to anything outside the repository.

The layers, from the bottom (docs/DESIGN.md): ``estimation`` (the flight software) imports
nothing of ours but itself; ``sequences`` (the ground's command language) may read the
flight software's definitions in ``estimation`` and nothing else; ``sim`` (the simulator)
imports no ``server``, ``bench`` or ``cli``; ``server`` imports no ``bench`` or ``cli``;
``bench`` and ``cli`` may import everything. Imports are read with ``ast`` from every
module, wherever they stand: at the top, inside a function, under ``TYPE_CHECKING``;
relative ones resolved to the module they name.

Each check is a function of the parsed tree, so ``test_the_checks_see_*`` can run it on a
small broken tree of their own and see it fail.
"""

from __future__ import annotations

import ast
import re
import subprocess
from collections.abc import Iterable, Mapping
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# our top-level packages, and which of them each may import (itself always)
MAY_IMPORT: dict[str, frozenset[str]] = {
    "estimation": frozenset(),
    "sequences": frozenset({"estimation"}),
    "sim": frozenset({"estimation", "sequences"}),
    "server": frozenset({"estimation", "sequences", "sim"}),
    "bench": frozenset({"estimation", "sequences", "sim", "server", "cli"}),
    "cli": frozenset({"estimation", "sequences", "sim", "server", "bench"}),
}
PACKAGES = tuple(MAY_IMPORT)
# the packages whose size is pinned, the tests (which mirror them) among them
SIZED = (*PACKAGES, "tests")
MAX_LINES = 600
MAX_MODULES_PER_FOLDER = 15
# text no tracked file may hold: file names of a former workspace, a sibling folder, a
# development machine's home or work directory (system paths such as /usr/bin are fine);
# written so that this file does not hold them itself
OUTSIDE = re.compile(rb"seed 0{2}|\.\./shared|(?<![\w.])/(?:work|root|home)/")


def module_name(path: Path, root: Path) -> str:
    """``sim/loop/session.py`` -> ``sim.loop.session``; a package's ``__init__.py`` is the
    package."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules_of(root: Path, packages: Iterable[str]) -> dict[str, Path]:
    """Every module of ``packages`` under ``root``, by dotted name."""
    found = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            found[module_name(path, root)] = path
    return found


def imports_of(name: str, path: Path, known: Mapping[str, Path]) -> set[str]:
    """The modules of ours (``known``) that module ``name`` imports, anywhere in it. ``from
    P import X`` imports module ``P.X`` when there is one, else ``P`` itself; a relative
    import is resolved against ``name``'s package."""
    is_package = path.name == "__init__.py"
    package = name if is_package else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            submodules = [f"{base}.{a.name}" if base else a.name for a in node.names]
            targets = [t for t in submodules if t in known]
            if len(targets) < len(submodules):  # a name defined in ``base`` itself
                targets.append(base)
        else:
            continue
        for target in targets:
            # ``import a.b.c`` binds the deepest module we know of on that path
            while target and target not in known:
                target = target.rpartition(".")[0]
            if target and target != name:
                found.add(target)
    return found


def import_graph(root: Path, packages: Iterable[str]) -> dict[str, set[str]]:
    """Module -> the modules of ours it imports."""
    known = modules_of(root, packages)
    return {name: imports_of(name, path, known) for name, path in known.items()}


def layering_violations(graph: Mapping[str, set[str]]) -> list[str]:
    """``importer -> imported`` for every import a layer may not make."""
    wrong = []
    for importer, imported in sorted(graph.items()):
        mine = importer.split(".")[0]
        for target in sorted(imported):
            theirs = target.split(".")[0]
            if theirs != mine and theirs not in MAY_IMPORT[mine]:
                wrong.append(f"{importer} -> {target}")
    return wrong


def import_cycles(graph: Mapping[str, set[str]]) -> list[list[str]]:
    """One circle of imports (``[a, b, ..., a]``) in each strongly connected set of
    modules (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, successors = work[-1]
            for successor in successors:
                if successor not in graph:
                    continue
                if successor not in index:
                    index[successor] = low[successor] = len(index)
                    stack.append(successor)
                    on_stack.add(successor)
                    work.append((successor, iter(sorted(graph[successor]))))
                    break
                if successor in on_stack:
                    low[node] = min(low[node], index[successor])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        components.append(sorted(component))
    return [_circle_in(graph, set(component)) for component in components]


def _circle_in(graph: Mapping[str, set[str]], component: set[str]) -> list[str]:
    """A shortest path from the component's first module back to itself (breadth first)."""
    first = min(component)
    came_from: dict[str, str] = {}
    frontier = [first]
    while frontier:
        following = []
        for node in frontier:
            for successor in sorted(graph[node] & component):
                if successor == first:
                    path = [node]
                    while path[-1] != first:
                        path.append(came_from[path[-1]])
                    return [first, *reversed(path[:-1]), first]
                if successor not in came_from:
                    came_from[successor] = node
                    following.append(successor)
        frontier = following
    raise AssertionError(f"no circle in {component}")  # a component of 2+ has one


def long_modules(root: Path, packages: Iterable[str]) -> list[str]:
    """``path: lines`` of every module over ``MAX_LINES`` lines (as ``wc -l`` counts)."""
    found = []
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            lines = path.read_bytes().count(b"\n")
            if lines > MAX_LINES:
                found.append(f"{path.relative_to(root)}: {lines}")
    return found


def crowded_folders(root: Path, packages: Iterable[str]) -> list[str]:
    """``folder: modules`` of every folder with more than ``MAX_MODULES_PER_FOLDER``
    modules (``.py`` files other than ``__init__.py``), subfolders each on their own."""
    found = []
    for package in packages:
        top = root / package
        for folder in sorted([top, *(p for p in top.rglob("*") if p.is_dir())]):
            if folder.name == "__pycache__":
                continue
            count = sum(1 for p in folder.glob("*.py") if p.name != "__init__.py")
            if count > MAX_MODULES_PER_FOLDER:
                found.append(f"{folder.relative_to(root)}: {count}")
    return found


def outside_references(root: Path, files: Iterable[str]) -> list[str]:
    """``file:line: text`` of every line of ``files`` that names something outside the
    repository (``OUTSIDE``)."""
    found = []
    for name in files:
        path = root / name
        if not path.is_file():  # deleted in the work tree, not yet in the index
            continue
        for number, line in enumerate(path.read_bytes().splitlines(), start=1):
            if OUTSIDE.search(line):
                found.append(f"{name}:{number}: {line.decode(errors='replace').strip()[:120]}")
    return found


def tracked_files(root: Path) -> list[str]:
    """The files git tracks in ``root`` (the test is skipped outside a git checkout)."""
    try:
        done = subprocess.run(
            ["git", "ls-files", "-z"], cwd=root, capture_output=True, check=True, timeout=60
        )
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout")
    return [name for name in done.stdout.decode().split("\0") if name]


# ---- the repository ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    found = import_graph(ROOT, PACKAGES)
    assert len(found) > 100 and "sim.loop.session" in found  # the walk found the project
    return found


def test_each_layer_imports_only_the_layers_below_it(graph: dict[str, set[str]]) -> None:
    found = layering_violations(graph)
    assert found == [], "imports across the layers: " + ", ".join(found)


def test_the_flight_software_imports_nothing_of_ours_but_itself(
    graph: dict[str, set[str]],
) -> None:
    outside = {t for n, ts in graph.items() if n.startswith("estimation") for t in ts}
    assert {t.split(".")[0] for t in outside} <= {"estimation"}


def test_no_import_circle(graph: dict[str, set[str]]) -> None:
    cycles = import_cycles(graph)
    assert cycles == [], "import circles: " + "; ".join(" -> ".join(c) for c in cycles)


def test_no_module_over_600_lines() -> None:
    found = long_modules(ROOT, SIZED)
    assert found == [], "over 600 lines: " + ", ".join(found)


def test_no_folder_over_15_modules() -> None:
    found = crowded_folders(ROOT, SIZED)
    assert found == [], "over 15 modules: " + ", ".join(found)


def test_no_file_names_anything_outside_the_repository() -> None:
    found = outside_references(ROOT, tracked_files(ROOT))
    assert found == [], "\n".join(found)


# ---- the checks on broken trees of their own ---------------------------------------------------


def _tree(root: Path, files: Mapping[str, str]) -> Path:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


def test_the_checks_see_a_layer_broken_anywhere_in_a_module(tmp_path: Path) -> None:
    root = _tree(
        tmp_path,
        {
            "estimation/__init__.py": "",
            "estimation/a.py": "def f():\n    from sim import b\n",
            "estimation/c.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
            "    import server.d\n",
            "estimation/e.py": "from . import f\nfrom .f import g\n",
            "estimation/f.py": "g = 1\n",
            "sequences/__init__.py": "",
            "sequences/x.py": "from ..sim.b import thing\nimport estimation.f\n",
            "sequences/y.py": "from .. import sim\n",
            "sim/__init__.py": "",
            "sim/b.py": "thing = 1\nimport bench.r\n",
            "server/__init__.py": "",
            "server/d.py": "from cli import main\n",
            "bench/__init__.py": "",
            "bench/r.py": "import server.d, cli.main\n",
            "cli/__init__.py": "",
            "cli/main.py": "from bench import r\n",
        },
    )
    graph = import_graph(root, PACKAGES)
    assert graph["estimation.e"] == {"estimation.f"}
    assert layering_violations(graph) == [
        "estimation.a -> sim.b",
        "estimation.c -> server.d",
        "sequences.x -> sim.b",
        "sequences.y -> sim",
        "server.d -> cli.main",
        "sim.b -> bench.r",
    ]
    assert import_cycles(graph) == [["bench.r", "cli.main", "bench.r"]]


def test_the_checks_see_a_longer_circle(tmp_path: Path) -> None:
    graph = {"a": {"b"}, "b": {"c", "x"}, "c": {"a"}, "x": set(), "y": {"y"}}
    assert import_cycles(graph) == [["a", "b", "c", "a"]]


def test_the_checks_see_sizes_and_outside_references(tmp_path: Path) -> None:
    long_text = "x = 1\n" * (MAX_LINES + 1)
    files = {f"sim/world/m{i}.py": "" for i in range(MAX_MODULES_PER_FOLDER + 1)}
    files |= {"sim/__init__.py": "", "sim/world/__init__.py": "", "sim/long.py": long_text}
    files["sim/notes.py"] = (
        "# as in seed 0" + "02\n# see ../" + "shared/REFERENCES.md\n"
        "DATA = '/ho" + "me/me/data'\nBROWSER = '/usr/bin/chromium'\n"
    )
    root = _tree(tmp_path, files)
    assert long_modules(root, ["sim"]) == [f"sim/long.py: {MAX_LINES + 1}"]
    assert crowded_folders(root, ["sim"]) == [f"sim/world: {MAX_MODULES_PER_FOLDER + 1}"]
    found = outside_references(root, ["sim/notes.py", "sim/long.py"])
    assert [f.split(":")[1] for f in found] == ["1", "2", "3"]
