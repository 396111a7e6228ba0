"""The examples run as a user would run them (they use only the public API)."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = sorted((Path(__file__).resolve().parent.parent / "examples").glob("*.py"))
PUBLIC = set(__import__("mechanism").__all__)


DEMO = Path(__file__).resolve().parent.parent / "mechanism" / "demo.py"


@pytest.mark.parametrize("path", [*EXAMPLES, DEMO], ids=[p.stem for p in [*EXAMPLES, DEMO]])
def test_example_uses_only_the_public_api(path):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            modules = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module or ""]
            )
            assert all(not m.startswith("mechanism.") for m in modules), (
                f"{path.name} imports {modules}"
            )
        if (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.value.id == "mechanism"
        ):
            assert node.attr in PUBLIC | {"__file__"}, (
                f"{path.name} uses mechanism.{node.attr}, not public"
            )


@pytest.mark.slow
@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_example_runs(path, tmp_path):
    result = subprocess.run(
        [sys.executable, str(path)], capture_output=True, text=True, cwd=tmp_path, timeout=600
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.strip()
