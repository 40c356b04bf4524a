"""The house rules of `docs/conventions.md` ("The house: packages and the layers of `fleet/`"), checked with `ast`:
which package may import which,
no loose module at `fleet/`'s top, no import from a lower layer of `fleet/` to a higher one, and no cycle."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LIBRARIES = ("scenes", "robots", "coordinator", "perception", "fleet")

# Each of fleet/'s packages and the layer it stands on: a package imports only packages of lower layers (and itself).
FLEET_LAYERS: dict[str, int] = {
    "fleet.common": 0,
    "fleet.bus": 1,
    "fleet.snapshot": 2,
    "fleet.record": 3,
    "fleet.sim": 4,
    "fleet.monitor": 4,
    "fleet.ros": 4,
    "fleet.robot_tools": 5,
    "fleet.sight": 5,
    "fleet.foxglove": 5,
    "fleet.nodes": 6,
    "fleet.twin": 6,
    "fleet.env": 6,
    "fleet.run": 7,
    "fleet.sweep": 8,
    "fleet.bench": 8,
    "fleet.cli": 9,
    "fleet.__main__": 10,
}
# What each library may import of the others (DESIGN.md's rules of the house).
MAY_IMPORT: dict[str, set[str]] = {
    "scenes": set(),
    "robots": {"scenes"},
    "coordinator": {"robots", "scenes"},
    "perception": set(),  # pixels in, detections out: it knows no scene, robot or line
    "fleet": {"robots", "coordinator", "scenes", "perception"},
}


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _type_only(tree: ast.Module) -> set[int]:
    """Ids of the import nodes under `if TYPE_CHECKING:`: names for type hints, never imported when the code runs."""
    return {
        id(n)
        for block in ast.walk(tree)
        if isinstance(block, ast.If) and ast.unparse(block.test).endswith("TYPE_CHECKING")
        for n in ast.walk(block)
    }


def _imports(path: Path, runtime_only: bool = False) -> set[str]:
    """Every module this file imports, absolute, at any depth (a deferred import counts as much as a top one; with
    `runtime_only`, those for type hints alone do not count)."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    tree = ast.parse(path.read_text(), str(path))
    skip = _type_only(tree) if runtime_only else set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                found.add(".".join(base + ([node.module] if node.module else [])))
            else:
                found.add(node.module or "")
    return found


def _sources(library: str) -> list[Path]:
    return sorted((ROOT / library).rglob("*.py"))


def _fleet_package(module: str) -> str:
    return ".".join(module.split(".")[:2])


def test_libraries_import_only_what_the_house_allows():
    broken = []
    for library in LIBRARIES:
        allowed = MAY_IMPORT[library] | {library}
        for path in _sources(library):
            for imported in _imports(path):
                top = imported.split(".")[0]
                if top in LIBRARIES and top not in allowed:
                    broken.append(f"{path.relative_to(ROOT)} imports {imported}")
                if library in ("robots", "coordinator", "scenes", "perception") and top in ("sapien", "zenoh"):
                    broken.append(f"{path.relative_to(ROOT)} imports {imported}: {library}/ is a library")
    assert not broken, "\n".join(broken)


def test_fleet_has_no_loose_module_at_its_top():
    loose = [p.name for p in (ROOT / "fleet").glob("*.py") if p.name not in ("__init__.py", "__main__.py")]
    assert not loose, f"fleet/ keeps its modules in packages: {loose}"
    packages = {f"fleet.{p.name}" for p in (ROOT / "fleet").iterdir() if (p / "__init__.py").exists()}
    assert packages == set(FLEET_LAYERS) - {"fleet.__main__"}, "every package of fleet/ has its layer in this test"
    for package in packages:
        init = ROOT / package.replace(".", "/") / "__init__.py"
        assert ast.get_docstring(ast.parse(init.read_text())), f"{package} says in a docstring what lives there"


def test_fleet_imports_run_down_the_layers_only():
    upward = []
    for path in _sources("fleet"):
        mine = _fleet_package(_module_name(path))
        for imported in _imports(path):
            theirs = _fleet_package(imported)
            if theirs.startswith("fleet.") and theirs != mine and FLEET_LAYERS[theirs] >= FLEET_LAYERS[mine]:
                upward.append(
                    f"{path.relative_to(ROOT)} ({mine}, layer {FLEET_LAYERS[mine]}) imports {imported} (layer "
                    f"{FLEET_LAYERS[theirs]})"
                )
    assert not upward, "\n".join(upward)


def _import_graph(library: str, runtime_only: bool) -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {}
    for path in _sources(library):
        graph[_module_name(path)] = set()
    for path in _sources(library):
        imported = _imports(path, runtime_only=runtime_only)
        graph[_module_name(path)] = {m for m in imported if m in graph and m != _module_name(path)}
    # A package's __init__ importing its own modules is how a package exposes them, not a cycle of design.
    for name, targets in graph.items():
        graph[name] = {t for t in targets if not t.startswith(name + ".")}
    return graph


@pytest.mark.parametrize("library", LIBRARIES)
def test_no_import_cycle_between_modules(library):
    cycle = _find_cycle(_import_graph(library, runtime_only=True))
    assert cycle is None, " -> ".join(cycle or [])


@pytest.mark.parametrize("library", LIBRARIES)
def test_no_import_cycle_through_type_hints(library):
    """A module that imports another for its type hints alone, while that one imports it, is a component that knows
    its host (or a host reached into by a helper): hand it what it needs instead (a `Protocol` names a shape)."""
    graph, found = _import_graph(library, runtime_only=False), set()
    while cycle := _find_cycle(graph):
        found.add(frozenset(cycle))
        graph[cycle[0]].discard(cycle[1])  # broken here to look for the next
    assert not found, f"import cycles: {[' -> '.join(sorted(c)) for c in found]}"


def _find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt) :] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def test_ruff_finds_nothing_to_lint_or_format():
    """`ruff check` and `ruff format --check` (settings in pyproject.toml, line length 120) are clean."""
    import shutil
    import subprocess
    import sys

    ruff = shutil.which("ruff", path=str(Path(sys.executable).parent)) or shutil.which("ruff")
    assert ruff, "ruff comes with the test extra"
    for argv in ([ruff, "check", "."], [ruff, "format", "--check", "."]):
        done = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, f"{' '.join(argv[1:])}:\n{done.stdout}{done.stderr}"


def test_ci_runs_the_readme_commands_as_written():
    """The README opens with two commands; `.ci/run` runs the test command exactly and the main job (briefly)."""
    readme = (ROOT / "README.md").read_text()
    blocks = [b.split("```")[0].strip() for b in readme.split("```bash\n")[1:3]]
    main_job, tests = blocks
    ci = (ROOT / ".ci" / "run").read_text()
    assert tests in ci.splitlines(), "the README's test command, line for line"
    assert any(line.startswith(main_job) for line in ci.splitlines()), "the README's main job"
    assert "venv" in main_job and "venv" in tests, "both commands make the virtualenv they install into"


def test_every_name_the_glossary_points_to_exists():
    """`docs/glossary.md` names the code that holds each word (`coordinator.tasks.Task`, ...): each such dotted name
    imports, so the glossary cannot keep a word the code renamed."""
    import importlib
    import re

    text = (ROOT / "docs" / "glossary.md").read_text()
    names = set(re.findall(r"`((?:scenes|robots|coordinator|fleet)(?:\.\w+)+)`", text))
    assert len(names) >= 15
    missing = []
    for name in sorted(names):
        parts = name.split(".")
        for cut in range(len(parts), 0, -1):  # the longest importable module, then attributes
            try:
                obj = importlib.import_module(".".join(parts[:cut]))
            except ImportError:
                continue
            try:
                for attr in parts[cut:]:
                    obj = getattr(obj, attr)
            except AttributeError:
                missing.append(name)
            break
        else:
            missing.append(name)
    assert not missing, f"the glossary names code that is not there: {missing}"


MAX_CLASS_LINES, MAX_FUNCTION_LINES = 400, 60


def test_the_benchmarks_page_holds_only_what_stands():
    """`docs/benchmarks.md` gives today's figures; a working session's number ("stop 57") marks history, which
    belongs in `docs/history.md`."""
    text = (ROOT / "docs" / "benchmarks.md").read_text()
    dated = [line for line in text.splitlines() if re.search(r"\bstop \d+", line, re.IGNORECASE)]
    assert not dated, f"docs/benchmarks.md dates figures by session (move them to docs/history.md): {dated}"


def test_no_class_over_400_lines_and_no_function_over_60():
    """A generous guard beside the checks that say what we mean (no single-use base, no component handed its host,
    no import cycle): a class past 400 lines holds more than one concern, a function past 60 more than one step."""
    too_long = []
    for library in LIBRARIES:
        for path in _sources(library):
            for node in ast.walk(ast.parse(path.read_text())):
                lines = getattr(node, "end_lineno", 0) - getattr(node, "lineno", 0) + 1
                if isinstance(node, ast.ClassDef) and lines > MAX_CLASS_LINES:
                    too_long.append(f"{path.relative_to(ROOT)}: class {node.name}, {lines} lines")
                elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and lines > MAX_FUNCTION_LINES:
                    too_long.append(f"{path.relative_to(ROOT)}: {node.name}, {lines} lines")
    assert not too_long, "\n".join(too_long)


def test_no_object_is_handed_the_object_that_makes_it():
    """A component handed its host (`Inputs(self)`) reads and writes whatever of the host it likes, as a mixin does:
    hand it the collaborators it uses (`fleet/run/supervision.py`)."""
    found = set()
    for library in LIBRARIES:
        for path in _sources(library):
            for cls in (n for n in ast.walk(ast.parse(path.read_text())) if isinstance(n, ast.ClassDef)):
                for call in (n for n in ast.walk(cls) if isinstance(n, ast.Call)):
                    func = call.func.value if isinstance(call.func, ast.Attribute) else call.func  # `X.of(self)`
                    args = [*call.args, *(k.value for k in call.keywords)]
                    made = func.id.lstrip("_") if isinstance(func, ast.Name) else ""
                    a_class = made[:1].isupper() and not made.isupper()  # CamelCase, not a CONSTANT's method
                    if a_class and any(isinstance(a, ast.Name) and a.id == "self" for a in args):
                        found.add((cls.name, func.id))
    assert not found, f"handed their host (host, component): {sorted(found)}"


def test_no_class_is_a_base_of_one_class_only():
    """A concern kept in a base class that only one class takes (a single-use mixin) shares its host's `self`: make
    it an object that owns its state and is handed its collaborators (`robots/skills/goal_outbox.py`)."""
    defined: set[str] = set()
    subclasses: dict[str, set[str]] = {}
    for library in LIBRARIES:
        for path in _sources(library):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.ClassDef):
                    defined.add(node.name)
                    for base in node.bases:
                        name = base.id if isinstance(base, ast.Name) else getattr(base, "attr", None)
                        if name:
                            subclasses.setdefault(name, set()).add(node.name)
    found: dict[str, set[str]] = {}
    for base, users in subclasses.items():
        if base in defined and len(users) == 1:
            found.setdefault(next(iter(users)), set()).add(base)
    assert not found, f"single-use bases (host: bases): {found}"
