"""Imports point down the layers, and the runtime core never imports JAX or PyTorch (ARCHITECTURE.md)."""

import ast
from pathlib import Path

import pytest

import toddlerbot

PACKAGE = Path(toddlerbot.__file__).parent
LAYER = {
    "errors": 0, "files": 0, "yaml_input": 0, "interrupts": 0, "metrics": 0, "registry": 0, "actuation": 0,
    "datasets": 0, "robot": 1,
    "sysid": 2, "sim": 2, "hardware": 2, "locomotion": 2, "design": 2,
    "policies": 3, "runtime": 3, "tasks": 3,
    "rl": 4, "teleop": 4, "dp": 4, "motion_editor": 4,
    "skills": 5,
    "cli": 6,
}
HEAVY = {"jax", "jaxlib", "flax", "brax", "optax", "orbax", "torch", "onnx"}
HEAVY_ALLOWED = {"rl", "dp"}
LAZY_HEAVY_ALLOWED = {"cli"}
"""The CLI may import heavy frameworks inside the commands that need them, never at module level."""


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE).parts
        if len(parts) > 1:
            yield parts[0], path
        elif path.stem != "__init__":  # a module of its own (files, errors, metrics, ...) is its own area
            yield path.stem, path


def _imports(path: Path, module_level_only: bool = False):
    tree = ast.parse(path.read_text())
    for node in tree.body if module_level_only else ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.module


@pytest.mark.parametrize("area,path", list(_modules()), ids=lambda v: str(v).split("toddlerbot/")[-1])
def test_imports_point_down(area, path):
    assert area in LAYER, f"{area} has no layer in ARCHITECTURE.md"
    for name in _imports(path):
        top = name.split(".")
        if top[0] == "toddlerbot" and len(top) > 1 and top[1] in LAYER:
            assert LAYER[top[1]] <= LAYER[area], f"{path.name} ({area}) imports {name} from a higher layer"
    if area in HEAVY_ALLOWED:
        return
    for name in _imports(path, module_level_only=area in LAZY_HEAVY_ALLOWED):
        assert name.split(".")[0] not in HEAVY, f"{path.name} ({area}) imports {name}; core modules must not need it"


LAZY_ONLY = {"onnxruntime"}
"""Optional runtimes that core modules may import inside the function that needs them, never at module level (the
robot runs with numpy, scipy and mujoco alone; `walk-rl` imports onnxruntime only to run an .onnx policy)."""


@pytest.mark.parametrize("area,path", [(a, p) for a, p in _modules() if a not in HEAVY_ALLOWED],
                         ids=lambda v: str(v).split("toddlerbot/")[-1])
def test_optional_runtimes_are_imported_lazily(area, path):
    for name in _imports(path, module_level_only=True):
        assert name.split(".")[0] not in LAZY_ONLY, f"{path.name} ({area}) imports {name} at module level"
