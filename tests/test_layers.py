"""The package's layering (docs/architecture.md): every module imports only from its own
layer or the layers below it, and no two modules import each other, directly or through
others. Imports under ``if TYPE_CHECKING:`` (annotations only) do not count; every other
import does, inside functions too."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "grasp_env"

#: Layers from the bottom: a module may import from its own layer and the ones below.
LAYERS = [
    ("errors", "arguments", "compiled"),
    ("core",),
    ("solvers",),
    ("sim",),
    ("kernel",),
    ("mechanics",),
    ("simulator", "testing"),
    ("planning",),
    ("envs", "render"),
    ("analyze", "cli", "__init__"),
]
RANK = {part: i for i, parts in enumerate(LAYERS) for part in parts}


def module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def layer_of(module: str) -> int:
    parts = module.split(".")
    return RANK[parts[1] if len(parts) > 1 else "__init__"]


def imports_of(path: Path) -> set[str]:
    """The grasp_env modules ``path`` imports (outside ``if TYPE_CHECKING:`` blocks)."""
    tree = ast.parse(path.read_text())
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip.update(id(n) for n in ast.walk(node))
    found = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("grasp_env"))
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("grasp_env"):
            for alias in node.names:
                sub = f"{node.module}.{alias.name}"
                found.add(sub if (PACKAGE.parent / sub.replace(".", "/")).exists() or
                          (PACKAGE.parent / (sub.replace(".", "/") + ".py")).exists()
                          else node.module)  # fmt: skip
    return found


def graph() -> dict[str, set[str]]:
    return {module_name(p): imports_of(p) for p in sorted(PACKAGE.rglob("*.py"))}


def test_every_module_has_a_layer() -> None:
    for module in graph():
        layer_of(module)  # KeyError names a module outside LAYERS


def test_imports_point_down_the_layers() -> None:
    upward = [
        f"{module} (layer {layer_of(module)}) imports {target} (layer {layer_of(target)})"
        for module, targets in graph().items()
        for target in targets
        if target != "grasp_env" and layer_of(target) > layer_of(module)
    ]
    assert not upward, "\n".join(upward)


def test_no_import_cycles() -> None:
    g = graph()
    g = {m: {t for t in ts if t in g and t != m} for m, ts in g.items()}
    state: dict[str, int] = {}  # 1: on the current path, 2: done

    def visit(m: str, path: list[str]) -> None:
        state[m] = 1
        for t in sorted(g[m]):
            if state.get(t) == 1:
                raise AssertionError("import cycle: " + " -> ".join([*path, m, t]))
            if t not in state:
                visit(t, [*path, m])
        state[m] = 2

    for m in sorted(g):
        if m not in state:
            visit(m, [])
