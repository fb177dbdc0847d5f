"""The packages' layering (docs/architecture.md): in ``grasp_env`` and in ``agents``, every
module imports only from its own layer or the layers below it, and no two modules import
each other, directly or through others; ``grasp_env`` imports nothing of ``agents``, which
sits on top of it. Imports under ``if TYPE_CHECKING:`` (annotations only) do not count;
every other import does, inside functions too."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: Layers from the bottom, per package: a module may import from its own layer and the ones
#: below.
LAYERS = {
    "grasp_env": [
        ("errors", "arguments", "compiled"),
        ("core",),
        ("solvers",),
        ("sim",),
        ("kernel",),
        ("mechanics",),
        ("simulator", "testing"),
        ("planning",),
        ("envs", "render", "view"),
        ("analyze", "cli", "__init__"),
    ],
    "agents": [
        ("__init__",),
        (
            "config",
            "wrappers",
            "batched",
            "plan_figures",
            "plan_report",
            "grip_branches",
            "provenance",
        ),
        (
            "callbacks",
            "scripted_policy",
            "scripted",
            "rllib_policy",
            "rllib_config",
            "rllib_training",
        ),
        ("planner_base", "planner_agents"),
        ("models",),
        ("episodes", "summary", "sweep_page", "expert", "cloning", "imitation_page"),
        (
            "train_ppo",
            "train_rllib",
            "evaluate",
            "learning_curves",
            "imitation",
            "planner_starts",
        ),
    ],
}
#: The commands of ``agents`` (its top layer), none of which imports another.
COMMANDS = {
    "agents.train_ppo",
    "agents.train_rllib",
    "agents.evaluate",
    "agents.learning_curves",
    "agents.imitation",
    "agents.planner_starts",
}
PACKAGES = list(LAYERS)


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def layer_of(module: str) -> int:
    package, *parts = module.split(".")
    rank = {part: i for i, names in enumerate(LAYERS[package]) for part in names}
    return rank[parts[0] if parts else "__init__"]


def imports_of(path: Path, prefixes: tuple[str, ...]) -> set[str]:
    """The modules of the packages ``prefixes`` that ``path`` imports (outside ``if
    TYPE_CHECKING:`` blocks)."""
    tree = ast.parse(path.read_text())
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip.update(id(n) for n in ast.walk(node))

    def ours(name: str) -> bool:
        return name.split(".")[0] in prefixes

    found = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names if ours(a.name))
        elif isinstance(node, ast.ImportFrom) and ours(node.module or ""):
            for alias in node.names:
                sub = f"{node.module}.{alias.name}"
                found.add(sub if (ROOT / sub.replace(".", "/")).exists() or
                          (ROOT / (sub.replace(".", "/") + ".py")).exists()
                          else node.module)  # fmt: skip
    return found


def graph(package: str, prefixes: tuple[str, ...] | None = None) -> dict[str, set[str]]:
    """Each module of ``package`` and the modules of ``prefixes`` (default: ``package``) it
    imports."""
    prefixes = prefixes or (package,)
    return {module_name(p): imports_of(p, prefixes) for p in sorted((ROOT / package).rglob("*.py"))}


def upward(g: dict[str, set[str]], package: str) -> list[str]:
    """The imports of ``g`` that point up ``package``'s layers."""
    return [
        f"{module} (layer {layer_of(module)}) imports {target} (layer {layer_of(target)})"
        for module, targets in g.items()
        for target in targets
        if target != package and layer_of(target) > layer_of(module)
    ]


def cycle(g: dict[str, set[str]]) -> list[str] | None:
    """An import cycle of ``g`` (modules in import order, the first repeated last), or None."""
    g = {m: {t for t in ts if t in g and t != m} for m, ts in g.items()}
    state: dict[str, int] = {}  # 1: on the current path, 2: done

    def visit(m: str, path: list[str]) -> list[str] | None:
        state[m] = 1
        for t in sorted(g[m]):
            if state.get(t) == 1:
                return [*path, m, t]
            if t not in state and (found := visit(t, [*path, m])):
                return found
        state[m] = 2
        return None

    for m in sorted(g):
        if m not in state and (found := visit(m, [])):
            return found
    return None


@pytest.mark.parametrize("package", PACKAGES)
def test_every_module_has_a_layer(package) -> None:
    for module in graph(package):
        layer_of(module)  # KeyError names a module outside LAYERS


@pytest.mark.parametrize("package", PACKAGES)
def test_imports_point_down_the_layers(package) -> None:
    found = upward(graph(package), package)
    assert not found, "\n".join(found)


@pytest.mark.parametrize("package", PACKAGES)
def test_no_import_cycles(package) -> None:
    found = cycle(graph(package))
    assert found is None, "import cycle: " + " -> ".join(found or [])


def test_commands_import_no_other_command() -> None:
    found = [
        f"{module} imports {target}"
        for module, targets in graph("agents").items()
        if module in COMMANDS
        for target in targets & COMMANDS
        if target != module
    ]
    assert not found, "\n".join(found)


def test_grasp_env_imports_nothing_of_agents() -> None:
    found = {m: ts for m, ts in graph("grasp_env", ("agents",)).items() if ts}
    assert not found, found


def test_the_checks_find_an_upward_import_and_a_cycle() -> None:
    g = {"agents.config": {"agents.models"}, "agents.models": {"agents.config"}}
    assert upward(g, "agents") == ["agents.config (layer 1) imports agents.models (layer 4)"]
    assert cycle(g) == ["agents.config", "agents.models", "agents.config"]
    assert cycle({"agents.config": set(), "agents.models": {"agents.config"}}) is None
