"""The import graph is one-way: no cycles between modules or packages, no upward or sideways imports.

Layers, bottom to top (ARCHITECTURE.md):

    scenes                      what the rest stands on, in three layers of its own (SCENES_LAYER):
                                  files, images, cli/, report/, metrics and the description's plain inputs;
                                  the scene description (description, lights, sensor, geometry, ...);
                                  folder/ (the object folder on disk) | renderer/ (Mitsuba), siblings
    wildgen | unips | validate  siblings: data generation, the model, the physical check;
                                none of them imports another
    orchestrate                 demo, benchmark, training recipe (may import all of the above)
    bench | tests               scripts and tests (may import anything)

Every import counts, also the lazy ones inside functions and `if TYPE_CHECKING:` blocks: they run
(or are read) all the same and tie the modules together.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYER = {"scenes": 0, "wildgen": 1, "unips": 1, "validate": 1, "orchestrate": 2, "bench": 3, "tests": 3}
PACKAGES = ("scenes", "wildgen", "unips", "validate", "orchestrate")
SIBLINGS_MAY_IMPORT_EACH_OTHER = False  # wildgen, unips, validate


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    out = {}
    for top in LAYER:
        for path in sorted((ROOT / top).rglob("*.py")):
            out[_module_name(path)] = path
    return out


MODULES = _modules()


def _resolve(name: str) -> str | None:
    """The project module `name` refers to (itself, or its longest known prefix), None if external."""
    while name:
        if name in MODULES:
            return name
        name = name.rpartition(".")[0]
    return None


def _imports(module: str, path: Path) -> set[str]:
    """Project modules imported anywhere in the file (module level and inside functions)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    is_package = path.name == "__init__.py"
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".") if is_package else module.split(".")[:-1]
                base = base[: len(base) - (node.level - 1)]
                prefix = ".".join(base + ([node.module] if node.module else []))
            else:
                prefix = node.module or ""
            # `from pkg import sub` imports the submodule pkg.sub when there is one.
            names = [f"{prefix}.{a.name}" if f"{prefix}.{a.name}" in MODULES else prefix for a in node.names]
        else:
            continue
        for name in names:
            target = _resolve(name)
            if target is not None and target != module:
                found.add(target)
    return found


GRAPH = {m: _imports(m, p) for m, p in MODULES.items()}


def _top(module: str) -> str:
    return module.split(".")[0]


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of the directed graph, or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def test_graph_is_not_empty():
    """The parser sees the project (guards the other tests against passing vacuously)."""
    assert {"scenes.folder.format", "unips.inference", "validate.rerender", "orchestrate.benchmark"} <= set(MODULES)
    assert "scenes.folder.format" in GRAPH["validate.io"]
    assert "unips.inference" in GRAPH["orchestrate.benchmark"]


def test_no_module_cycle():
    cycle = _cycle({m: {t for t in ts if _top(t) in PACKAGES} for m, ts in GRAPH.items() if _top(m) in PACKAGES})
    assert cycle is None, "import cycle between modules: " + " -> ".join(cycle)


def test_no_package_cycle():
    pkg_graph: dict[str, set[str]] = {}
    for m, targets in GRAPH.items():
        if _top(m) not in PACKAGES:
            continue
        # Sub-packages count as packages of their own (unips.models inside unips).
        src = m if (MODULES[m].name == "__init__.py") else m.rpartition(".")[0]
        for t in targets:
            dst = t if MODULES[t].name == "__init__.py" else t.rpartition(".")[0]
            if dst != src and not src.startswith(dst + ".") and _top(t) in PACKAGES:
                pkg_graph.setdefault(src, set()).add(dst)
    cycle = _cycle(pkg_graph)
    assert cycle is None, "import cycle between packages: " + " -> ".join(cycle)


@pytest.mark.parametrize("module", sorted(MODULES))
def test_imports_go_down(module):
    src = _top(module)
    bad = []
    for target in sorted(GRAPH[module]):
        dst = _top(target)
        if dst == src:
            continue
        if LAYER[dst] > LAYER[src]:
            bad.append(f"{target} (upward: {dst} is above {src})")
        elif LAYER[dst] == LAYER[src] and not (SIBLINGS_MAY_IMPORT_EACH_OTHER and LAYER[src] == 1):
            bad.append(f"{target} (sideways: {src} and {dst} are siblings)")
    assert not bad, f"{module} imports " + ", ".join(bad)


# ------------------------------------------------------------------ the layers inside scenes

SCENES_LAYER = {
    # 0: files and pixels, the command-line machinery, what is shown to people, plain inputs without a description
    "scenes.files": 0, "scenes.exr": 0, "scenes.images": 0, "scenes.metrics": 0, "scenes.cli": 0, "scenes.report": 0,
    "scenes.dependencies": 0, "scenes.checks": 0, "scenes.colors": 0, "scenes.detail": 0, "scenes.procedural": 0,
    "scenes.tiff": 0,
    # 1: the scene description and what it is made of
    "scenes.description": 1, "scenes.lights": 1, "scenes.camera_sensor": 1, "scenes.geometry": 1, "scenes.meshes": 1,
    "scenes.envmaps": 1, "scenes.textures": 1, "scenes.surface": 1,
    # 2: siblings that stand on the description: the object folder on disk, and Mitsuba
    "scenes.folder": 2, "scenes.renderer": 2,
}
"""Every module of scenes (but its __init__) belongs to one entry (its own name or its sub-package's); it imports
only entries of its layer or below, and the two entries of layer 2 never import each other."""


def _group(module: str, table: dict[str, int]) -> str | None:
    """The entry of `table` a module belongs to: its own name or that of its closest enclosing package."""
    name = module
    while name and name not in table:
        name = name.rpartition(".")[0]
    return name or None


def _scenes_group(module: str) -> str | None:
    return _group(module, SCENES_LAYER)


def _inside_violations(module: str, table: dict[str, int], sealed: set[int]) -> list[str]:
    """The imports of `module` that break the layers of its package's `table`: upward, or sideways between two
    entries of one layer in `sealed` (layers whose entries are siblings that never import each other)."""
    top, group = _top(module), _group(module, table)
    assert group is not None, f"{module} has no place in the table of {top} (tests/test_layers.py, ARCHITECTURE.md)"
    bad = []
    for target in sorted(t for t in GRAPH[module] if _top(t) == top and t != top):
        other = _group(target, table)
        if other == group:
            continue
        if table[other] > table[group]:
            bad.append(f"{target} (upward: {other} is above {group})")
        elif table[other] == table[group] and table[group] in sealed:
            bad.append(f"{target} (sideways: {group} and {other} are siblings)")
    return bad


@pytest.mark.parametrize("module", sorted(m for m in MODULES if _top(m) == "scenes" and m != "scenes"))
def test_scenes_imports_go_down_inside_scenes(module):
    bad = _inside_violations(module, SCENES_LAYER, sealed={2})
    assert not bad, f"{module} imports " + ", ".join(bad)


def test_the_scenes_layer_check_can_fail():
    """A made-up import of the renderer by the object folder is refused (the test above is not vacuous)."""
    assert SCENES_LAYER[_scenes_group("scenes.folder.layouts")] == SCENES_LAYER[_scenes_group("scenes.renderer.render")]
    assert _scenes_group("scenes.folder.layouts") != _scenes_group("scenes.renderer.render")
    assert SCENES_LAYER[_scenes_group("scenes.images")] < SCENES_LAYER[_scenes_group("scenes.description")]


# ------------------------------------------------------------------ the rooms of validate

VALIDATE_ROOM = {
    # 0: what every mode shares: normal-map files and predictions, residuals, figures, perturbations, a capture's
    # record (observations) and what a capture can judge (judgeable, with the one table of image counts)
    "validate.io": 0, "validate.residuals": 0, "validate.figures": 0, "validate.perturb": 0,
    "validate.observations": 0, "validate.judgeable": 0,
    # 1: the modes, siblings: known scene, fitted (and refinement), capture diagnosis
    "validate.known": 1, "validate.fitted": 1, "validate.diagnosis": 1,
    # 2: the command lines, which use the modes
    "validate.rerender": 2, "validate.refine": 2,
}
"""Every module of validate (but its __init__) belongs to one room (its own name or its sub-package's); it imports
only rooms below its own, or its own, and the three modes never import each other."""


def _validate_room(module: str) -> str | None:
    return _group(module, VALIDATE_ROOM)


@pytest.mark.parametrize("module", sorted(m for m in MODULES if _top(m) == "validate" and m != "validate"))
def test_validate_imports_go_down_its_rooms(module):
    bad = _inside_violations(module, VALIDATE_ROOM, sealed={1, 2})
    assert not bad, f"{module} imports " + ", ".join(bad)


def test_the_validate_room_check_can_fail():
    """The three modes are separate rooms of one layer, above the shared modules (the test above is not vacuous)."""
    rooms = {_validate_room(m) for m in ("validate.known.rerender_passes", "validate.fitted.verdict",
                                         "validate.diagnosis.usable")}
    assert len(rooms) == 3 and {VALIDATE_ROOM[r] for r in rooms} == {1}
    assert VALIDATE_ROOM[_validate_room("validate.observations")] < VALIDATE_ROOM[_validate_room("validate.fitted.fit")]
    assert any(_validate_room(m) is None for m in ("validate.observations", "validate.nowhere"))


# ------------------------------------------------------------------ who may name an object-folder file

FOLDER_OWNERS = ("scenes.folder.format", "scenes.folder.layouts")
"""The object folder's files are named only here (the folder contract and the one reader's layout table);
everyone else uses their constants, so a renamed or added file changes one place."""


def _folder_file_names() -> set[str]:
    from scenes.folder import format as objfolder
    from scenes.folder import layouts

    names = {objfolder.SCENE_FILE, objfolder.MASK_FILE, objfolder.NORMAL_FILE, objfolder.AUX_DIR,
             objfolder.DILIGENT_LIGHTS, objfolder.DILIGENT_INTENSITIES, layouts.DILIGENT_LISTING}
    for entry in layouts.LAYOUT_TABLE:
        names.update(entry.ground_truth)
    return names


def _named_files(path: Path, names: set[str]) -> list[str]:
    """String literals (not docstrings or messages that merely mention a file) that are a folder file name
    or a path inside the aux folder."""
    tree = ast.parse(path.read_text(), filename=str(path))
    bare = {id(node.value) for node in ast.walk(tree) if isinstance(node, ast.Expr)}
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in bare:
            text = node.value
            if text in names or any(text.startswith(n + "/") or text.endswith("/" + n) for n in names):
                found.append(f"line {node.lineno}: {text!r}")
    return found


def test_only_the_folder_owners_name_object_folder_files():
    names = _folder_file_names()
    assert {"scene.json", "mask.png", "light_directions.txt"} <= names  # guards against a vacuous pass
    bad = {}
    for module, path in MODULES.items():
        if _top(module) in PACKAGES and module not in FOLDER_OWNERS:
            found = _named_files(path, names)
            if found:
                bad[module] = found
    assert not bad, f"modules other than {FOLDER_OWNERS} name object-folder files: {bad}"


def test_the_file_name_check_can_fail(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text(
        '"""Mentions scene.json in a docstring: fine."""\nP = folder / "scene.json"\nQ = f"{x}/mask.png"\n'
    )
    assert _named_files(probe, _folder_file_names()) == ["line 2: 'scene.json'", "line 3: '/mask.png'"]
