"""docs/DESIGN.md's one rule: the flight software (estimation/) imports nothing of sim/,
server/ or sequences/."""

import ast
from pathlib import Path

import estimation

FORBIDDEN = ("sim", "server", "sequences")


def test_estimation_imports_no_simulator_or_server_code() -> None:
    package = Path(estimation.__file__).parent
    modules = sorted(package.rglob("*.py"))
    assert len(modules) >= 5  # the walk really found the flight software
    offenders = []
    for path in modules:
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            names: list[str] = []
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            offenders += [f"{path.name}: {n}" for n in names if n.split(".")[0] in FORBIDDEN]
    assert offenders == []
