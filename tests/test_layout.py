"""The package's rooms and layers (docs/architecture.md): imports only go down, never across
two rooms of one layer, and never in a circle. Every import counts, also those inside functions."""

import ast
import tomllib
from pathlib import Path

import networkx as nx
import pytest

REPO = Path(__file__).resolve().parent.parent
PACKAGE = REPO / "mechanism"
# the design card's top-level folders that the wheel maps into the package
MAPPED = {"mechanism.converters": REPO / "converters"}

# room -> layer; a room may import rooms of lower layers and itself only.
LAYERS = {
    "errors": 0,
    "tolerances": 0,
    "lazy": 0,
    "files": 1,
    "data": 1,
    "native": 2,
    "batch": 2,
    "converters": 2,  # native keeps its kernels in the files room's cache
    "kinematics": 3,
    "physics": 3,
    "machine": 4,
    "dynamics": 5,
    "inspection": 6,
    "sysid": 6,
    "steppers": 7,
    "testbench": 7,
    "api": 8,
    "demo": 8,
    "__init__": 8,
    "cli": 9,
    "__main__": 10,
}


def module_name(path: Path) -> str:
    for package, folder in MAPPED.items():
        if path.is_relative_to(folder):
            parts = (*package.split("."), *path.relative_to(folder).with_suffix("").parts)
            break
    else:
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def sources() -> list[Path]:
    return [
        *PACKAGE.rglob("*.py"),
        *(p for folder in MAPPED.values() for p in folder.rglob("*.py")),
    ]


def imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), str(path))
    found = set()
    package = (
        module_name(path) if path.name == "__init__.py" else module_name(path).rpartition(".")[0]
    )
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(
                    package.split(".")[: len(package.split(".")) - node.level + 1]
                    + ([base] if base else [])
                )
            found |= {f"{base}.{alias.name}" for alias in node.names}
            found.add(base)  # `from package import name` runs the package's __init__ too
    return {name for name in found if name == "mechanism" or name.startswith("mechanism.")}


def room(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def graph() -> nx.DiGraph:
    modules = {module_name(p): p for p in sources()}
    g = nx.DiGraph()
    for name, path in modules.items():
        g.add_node(name)
        for target in imports(path):
            while (
                target not in modules and "." in target
            ):  # `from mechanism.x import name` names a symbol
                target = target.rpartition(".")[0]
            if target != name and target in modules and target != "mechanism":
                g.add_edge(name, target)
    return g


@pytest.mark.slow
def test_every_room_has_a_layer():
    rooms = {room(m) for m in graph().nodes}
    assert rooms <= set(LAYERS), (
        f"give these a layer in this test and docs/architecture.md: {sorted(rooms - set(LAYERS))}"
    )


@pytest.mark.slow
def test_imports_only_go_down():
    wrong = []
    for source, target in graph().edges:
        a, b = room(source), room(target)
        if a != b and LAYERS[a] <= LAYERS[b]:
            wrong.append(f"{source} -> {target} ({a} layer {LAYERS[a]}, {b} layer {LAYERS[b]})")
    assert not wrong, "\n".join(wrong)


@pytest.mark.slow
def test_no_import_cycle():
    g = graph()
    # a package's __init__ exporting its own modules is how packages work, not a circle
    g.remove_edges_from([(a, b) for a, b in list(g.edges) if b.startswith(a + ".")])
    cycles = list(nx.simple_cycles(g))
    assert not cycles, cycles[:5]


@pytest.mark.slow
def test_the_converter_and_the_test_bench_stay_independent():
    g = graph()
    for source, target in g.edges:
        if room(source) == "converters" and room(target) != "converters":
            assert LAYERS[room(target)] < LAYERS["converters"], (
                f"{source} imports {target}: converters never import the simulator"
            )
        if room(source) == "testbench":
            assert room(target) != "sysid", (
                f"{source} imports {target}: the truth model must not know the diagnosis"
            )


def test_every_subpackage_names_a_curated_api_that_resolves():
    """Each room by concern lists its public API in ``__all__``; every name resolves to an object
    of the module it is listed from, and importing the package alone imports none of them."""
    import importlib
    import subprocess
    import sys

    rooms = [
        "dynamics",
        "files",
        "inspection",
        "kinematics",
        "machine",
        "physics",
        "sysid",
        "steppers",
        "batch",
        "converters",
        "testbench",
    ]
    for room in rooms:
        package = importlib.import_module(f"mechanism.{room}")
        names = getattr(package, "__all__", None)
        assert names, f"mechanism.{room} lists no public API"
        for name in names:
            assert getattr(package, name) is not None, f"mechanism.{room}.{name}"
    probe = (
        "import sys, mechanism.inspection, mechanism.sysid; "
        "print(any(m in sys.modules for m in ('fcl', 'mechanism.inspection.clearance', 'mechanism.sysid.diagnosis')))"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, cwd=PACKAGE.parent
    )
    assert out.stdout.strip() == "False", out.stderr


def test_the_commands_parser_imports_no_simulator_and_no_fitting_library():
    """Every start of ``mechanism`` builds the parser of every verb: their heavy imports (mujoco,
    scipy, trimesh, matplotlib) belong to the verb that runs (0.44 -> 0.18 s for the parser when
    the sweep's help stopped importing the sweep itself)."""
    import subprocess
    import sys

    heavy = ("mujoco", "scipy", "trimesh", "matplotlib", "mechanism.sysid.identification")
    probe = (
        "import sys; from mechanism.cli import build_parser; build_parser(); "
        f"print(sorted(m for m in {heavy!r} if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, cwd=PACKAGE.parent
    )
    assert out.stdout.strip() == "[]", (out.stdout, out.stderr)


def test_the_wheel_maps_the_design_cards_top_level_into_the_package():
    """pyproject lists every package (the mapped ones from their top-level folders), so the wheel
    misses none, and the top level is the card's: one copy of each file, nowhere else."""
    setuptools = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    on_disk = {module_name(p.parent / "__init__.py") for p in sources() if p.name == "__init__.py"}
    assert set(setuptools["packages"]) == on_disk | {"mechanism.assets"}
    for package, folder in MAPPED.items():
        assert setuptools["package-dir"][package] == folder.name
    assert setuptools["package-dir"]["mechanism.assets"] == "assets"
    for entry in (
        "pyproject.toml",
        "mechanism",
        "assets/mjcf",
        "assets/meshes",
        "converters",
        "tests",
        "README.md",
    ):
        assert (REPO / entry).exists(), entry
    assert not (PACKAGE / "converters").exists() and not (PACKAGE / "models").exists()


def test_ci_installs_with_the_home_folder_and_tests_with_an_empty_one():
    script = (REPO / ".ci" / "run").read_text()
    install, test = (
        script.index("make .venv/.installed"),
        script.index('HOME="$fresh_home" make test'),
    )
    assert install < test and "mktemp -d" in script


def test_test_helpers_live_in_their_package_and_bench_edits_no_import_path():
    """Helpers are imported as ``tests.helpers.<module>`` by tests, their subprocesses and bench/
    alike; a helper loose in tests/ or a ``sys.path`` edit in bench/ works only from some folders."""
    tests = REPO / "tests"
    loose = [
        p.name
        for p in tests.glob("*.py")
        if not p.name.startswith("test_") and p.name not in ("conftest.py", "__init__.py")
    ]
    assert not loose, f"move these helpers into tests/helpers/: {loose}"
    assert (tests / "__init__.py").is_file() and (tests / "helpers" / "__init__.py").is_file()
    import re

    bare = [
        p.name
        for p in tests.rglob("*.py")
        if re.search(
            r"^\s*(from|import) (test_\w+|conftest|helpers|support)\b", p.read_text(), re.M
        )
    ]
    assert not bare, (
        f"import test modules and helpers by their package (tests.<module>), not a bare name: {bare}"
    )
    edits = [
        str(p.relative_to(REPO))
        for p in (REPO / "bench").rglob("*.py")
        if "sys.path" in p.read_text()
    ]
    assert not edits, (
        f"bench/ runs as `python -m bench` from the repository root, where tests.helpers imports as is: {edits}"
    )
