"""Imports point down the layers, the runtime core never imports JAX or PyTorch, and the CLI starts without any
optional extra (ARCHITECTURE.md)."""

import ast
import os
import subprocess
import sys
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
    "skills": 5, "sessions": 5,
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


EXTRA_MODULES = ("jax", "jaxlib", "flax", "brax", "optax", "orbax", "mujoco.mjx", "tensorboardX", "onnx",
                 "onnxruntime", "torch", "wandb", "dynamixel_sdk", "serial", "adafruit_bno08x", "pyarrow", "av",
                 "pygame", "zmq", "msgpack", "viser", "rerun")
"""Top-level modules of the optional extras (pyproject.toml): `pip install toddlerbot` alone has none of them."""

_CLI_WITHOUT_EXTRAS = """
import sys
class Missing:  # importing an extra raises ModuleNotFoundError, as on a core install
    def find_spec(self, name, path=None, target=None):
        if name in {hidden!r}:
            raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
sys.meta_path.insert(0, Missing())
from toddlerbot.cli.main import main
sys.argv = ["toddlerbot", *{argv!r}]
main()
"""


@pytest.mark.parametrize("argv", [["--help"], ["rl", "train", "--help"], ["teleop", "--help"], ["sim", "run", "--help"],
                                  ["hw", "run", "--help"], ["dp", "--help"], ["manip", "--help"]], ids=" ".join)
def test_the_cli_starts_on_a_core_install(argv):
    """Every area loads with the core dependencies alone (a GPU image without pyzmq could not start `rl train`):
    an extra is imported by the command that needs it, which then names the extra."""
    out = subprocess.run([sys.executable, "-c", _CLI_WITHOUT_EXTRAS.format(hidden=EXTRA_MODULES, argv=argv)],
                         capture_output=True, text=True, timeout=120, env={**os.environ, "COLUMNS": "200"})
    assert out.returncode == 0, out.stderr[-2000:]
    assert "Usage: toddlerbot" in out.stdout


def test_the_leader_link_without_its_extra_names_the_extra():
    script = _CLI_WITHOUT_EXTRAS.split("from toddlerbot.cli.main")[0] + (
        "from toddlerbot.teleop.link import LinkSubscriber\n"
        "try:\n    LinkSubscriber()\nexcept Exception as exc:\n    print(type(exc).__name__, exc)\n")
    out = subprocess.run([sys.executable, "-c", script.format(hidden=EXTRA_MODULES)], capture_output=True,
                         text=True, timeout=120)
    assert out.stdout.strip() == ("ToddlerbotError the leader-follower link needs pyzmq and msgpack: "
                                  "pip install 'toddlerbot[manip]'"), out.stderr[-2000:]


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _import_graph() -> dict[str, set[str]]:
    """Module -> the toddlerbot modules it imports anywhere: at module level, inside functions, and under
    TYPE_CHECKING (`from toddlerbot.rl import train` names the module ``toddlerbot.rl.train``)."""
    modules = {_module_name(path): path for path in PACKAGE.rglob("*.py")}

    def resolve(name: str) -> str | None:
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name or None

    graph: dict[str, set[str]] = {}
    for module, path in modules.items():
        package = module if path.name == "__init__.py" else module.rpartition(".")[0]
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    base = ".".join([*package.split(".")[: len(package.split(".")) - node.level + 1], base]).rstrip(".")
                names = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base for alias in node.names]
            else:
                continue
            targets |= {resolve(n) for n in names if n.startswith("toddlerbot")} - {None, module}
        graph[module] = targets  # type: ignore[assignment]
    return graph


def test_no_import_circles_between_modules():
    """No module reaches itself through its imports, lazy and type-checking imports included: a circle makes
    import order matter and hides which module is the lower one (ARCHITECTURE.md)."""
    graph = _import_graph()
    circles = []
    for start in graph:
        stack, seen = [(start, (start,))], set()
        while stack:
            node, path = stack.pop()
            for nxt in graph[node]:
                if nxt == start:
                    circles.append(" -> ".join((*path, start)))
                elif nxt not in seen:
                    seen.add(nxt)
                    stack.append((nxt, (*path, nxt)))
    assert not circles, "import circles:\n" + "\n".join(sorted(set(circles))[:10])
    assert len(graph) > 150 and sum(len(t) for t in graph.values()) > 600  # the whole package was read
