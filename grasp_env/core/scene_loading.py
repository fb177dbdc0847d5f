"""Scenes from YAML files, bundled names or dicts, validated field by field: every bad input
raises :class:`~grasp_env.errors.SceneError` naming the field and the value.

:func:`load_scene` accepts a bundled scene name (a file in the package's
``grasp_env/scenes/``, installed as package data), a path to a YAML file, or a dict in the
schema of docs/conventions.md; the accepted ranges are in :mod:`grasp_env.core.scene`, the
checks of the fields in :mod:`grasp_env.core.scene_validation`.
"""

from __future__ import annotations

import copy
import importlib.resources
import os
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from grasp_env.core.scene import Scene
from grasp_env.core.scene_validation import convex_polygon, scene_from_dict
from grasp_env.errors import SceneError

if TYPE_CHECKING:
    from importlib.resources.abc import Traversable

__all__ = [
    "SCENES_DIR",
    "SCENE_SUFFIXES",
    "bundled_scenes",
    "convex_polygon",
    "load_scene",
    "scaled_scene_dict",
    "scene_from_dict",
]

#: File suffixes that make a string a path rather than a bundled name (see :func:`load_scene`).
SCENE_SUFFIXES = (".yaml", ".yml")


def _scenes_dir() -> Traversable:
    override = os.environ.get("GRASP_ENV_SCENES")
    if override:
        return Path(override)
    return importlib.resources.files("grasp_env").joinpath("scenes")


#: Folder of the bundled scenes: ``grasp_env/scenes/`` inside the installed package (package
#: data, read through :mod:`importlib.resources`; a :class:`pathlib.Path` unless the package is
#: imported from a zip file). The environment variable ``GRASP_ENV_SCENES``, read at import,
#: replaces it by another folder.
SCENES_DIR = _scenes_dir()

#: Numbers as YAML 1.2's core schema reads them, decimal forms only: integers, and decimals
#: with an optional exponent (``1e1`` is 10.0), ``.inf`` and ``.nan``. PyYAML follows YAML 1.1,
#: which reads ``1e1`` as a string, ``010`` as 8, ``9_81`` as 981 and ``1:30`` as 90; here
#: ``010`` is 10, and ``9_81``, ``1:30`` and hexadecimal stay strings, which number fields refuse.
_INT = re.compile(r"^[-+]?[0-9]+$")
_FLOAT = re.compile(
    r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
    r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"
)
_INT_TAG = "tag:yaml.org,2002:int"
_FLOAT_TAG = "tag:yaml.org,2002:float"
_MERGE_TAG = "tag:yaml.org,2002:merge"


#: Deepest nesting of values a scene file may have (the schema needs 5: a number in a point in
#: ``object.vertices``); PyYAML composes nested values by recursion, which a deeper file
#: would take past Python's recursion limit.
MAX_DEPTH = 32


class _SceneLoader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 numbers (``_INT``, ``_FLOAT``), no duplicate keys
    (YAML forbids them; PyYAML would keep the last silently, e.g. a second ``palm:`` block),
    no aliases (``*name``: a few nested ones stand for billions of values, which a field kept
    as text spells out, and the schema has no use for them), values nested at most
    ``MAX_DEPTH`` deep, and every failure to construct a value (``!!bool maybe``,
    ``!!float abc``) a YAML error at the value's line."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent: yaml.Node | None, index: Any) -> yaml.Node:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise SceneError(
                f"alias *{event.anchor} on line {event.start_mark.line + 1}: scene files may "
                "not use aliases; write the value out"
            )
        if self._depth >= MAX_DEPTH:
            line = self.peek_event().start_mark.line + 1
            raise SceneError(f"values nested more than {MAX_DEPTH} levels deep on line {line}")
        self._depth += 1
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_object(self, node: yaml.Node, deep: bool = False) -> Any:
        try:
            return super().construct_object(node, deep=deep)
        except (yaml.YAMLError, SceneError):
            raise
        except (ArithmeticError, AttributeError, KeyError, TypeError, ValueError):
            tag = node.tag.replace("tag:yaml.org,2002:", "!!")
            value = repr(node.value) if isinstance(node, yaml.ScalarNode) else f"this {node.id}"
            raise yaml.constructor.ConstructorError(
                None, None, f"{value} is not a valid {tag}", node.start_mark
            ) from None

    def construct_mapping(self, node: yaml.Node, deep: bool = False) -> dict:
        if isinstance(node, yaml.MappingNode):
            first: dict[Any, int] = {}
            for key_node, _ in node.value:
                if isinstance(key_node, yaml.ScalarNode) and key_node.tag != _MERGE_TAG:
                    key = self.construct_object(key_node)
                    line = key_node.start_mark.line + 1
                    if key in first:
                        raise SceneError(
                            f"duplicate key {key!r} on line {line} (first on line {first[key]})"
                        )
                    first[key] = line
        return super().construct_mapping(node, deep=deep)

    def construct_yaml_int(self, node: yaml.Node) -> int:
        """A decimal integer (YAML 1.1 would read ``010`` as octal)."""
        text = self.construct_scalar(node)
        if not _INT.match(text):  # an explicit !!int tag on something else
            raise yaml.constructor.ConstructorError(
                None, None, f"{text!r} is not a decimal integer", node.start_mark
            )
        return int(text)


_SceneLoader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag not in (_INT_TAG, _FLOAT_TAG)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_SceneLoader.add_implicit_resolver(_INT_TAG, _INT, list("-+0123456789"))
_SceneLoader.add_implicit_resolver(_FLOAT_TAG, _FLOAT, list("-+.0123456789"))
_SceneLoader.add_constructor(_INT_TAG, _SceneLoader.construct_yaml_int)


def bundled_scenes() -> list[str]:
    """Names of the bundled scenes (the ``*.yaml`` files of :data:`SCENES_DIR`), sorted."""
    if not SCENES_DIR.is_dir():
        return []
    return sorted(
        p.name[: -len(".yaml")]
        for p in SCENES_DIR.iterdir()
        if p.name.endswith(".yaml") and p.is_file()
    )


def _is_path(spec: str | os.PathLike) -> bool:
    """Whether ``spec`` names a file (see :func:`load_scene`), not a bundled scene."""
    if not isinstance(spec, str):
        return True  # os.PathLike
    separators = {"/", os.sep, os.altsep} - {None}
    return any(sep in spec for sep in separators) or spec.lower().endswith(SCENE_SUFFIXES)


def load_scene(spec: str | os.PathLike | dict | Scene) -> Scene:
    """Load a scene from a bundled name, a YAML path, a dict, or pass a :class:`Scene` through.

    A string is a **path** when it contains a path separator (``"./fig13"``,
    ``"scenes/my.yaml"``) or ends in ``.yaml`` or ``.yml`` (``"my_scene.yaml"``, read from the
    working directory), and so is any :class:`os.PathLike` (``pathlib.Path("fig13")``). Any
    other string is a **bundled name** (:func:`bundled_scenes`): ``load_scene("fig13")`` is
    always the bundled scene, whatever files or folders the working directory holds; an
    unknown name raises :class:`SceneError` listing the bundled names. A path is never
    looked up among the bundled scenes.

    Args:
        spec: a bundled name, a path to a YAML file in the scene schema (docs/conventions.md,
            "Scene schema"), a dict in that schema, or a :class:`Scene` (returned as it is).

    Returns:
        The validated scene; ``source`` holds the file it was read from (None for a dict).

    Raises:
        SceneError: an unknown bundled name, a file that is missing or unreadable, not
            valid YAML (the message names the file and the line) or in YAML the loader
            refuses (aliases, deep nesting: ``_SceneLoader``), or an invalid field (the
            message names the field and the value). ``SceneError`` is a ``ValueError``.
    """
    if isinstance(spec, Scene):
        return spec
    if isinstance(spec, dict):
        return scene_from_dict(spec)
    if not isinstance(spec, str | os.PathLike):
        raise SceneError(f"scene must be a bundled name, a path or a dict, got {spec!r}")
    if _is_path(spec):
        path: Traversable = Path(spec)
    else:
        names = bundled_scenes()
        if spec not in names:
            raise SceneError(
                f"not a bundled scene: {spec!r}; bundled: {names} (a file is read "
                f"only from a path with a separator or a .yaml/.yml suffix, e.g. './{spec}')"
            )
        path = SCENES_DIR.joinpath(f"{spec}.yaml")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise SceneError(f"scene file {str(path)!r} is not UTF-8 text: {exc.reason}") from None
    except (OSError, ValueError) as exc:  # ValueError: a path with a NUL byte
        reason = getattr(exc, "strerror", None) or str(exc)
        raise SceneError(f"scene file {str(path)!r} cannot be read: {reason}") from None
    try:
        data = yaml.load(text, Loader=_SceneLoader)
    except yaml.YAMLError as exc:
        raise SceneError(f"scene file {str(path)!r} is not valid YAML: {exc}") from None
    except SceneError as exc:  # a duplicate key, an alias, too deep a nesting
        raise SceneError(f"scene file {str(path)!r}: {exc}") from None
    return scene_from_dict(data, source=str(path))


def scaled_scene_dict(spec: dict[str, Any], k: float) -> dict[str, Any]:
    """A copy of the scene dict ``spec`` with every length times ``k``: the same scene at palm
    width ``k`` times its own. Densities are kept, so a given ``object.mass`` scales by
    ``k**2``, and torque limits (force times length) by ``k**3``."""
    d = copy.deepcopy(spec)
    palm = d["palm"]
    palm["width"] *= k
    palm["thickness"] *= k
    palm["pose"] = [palm["pose"][0] * k, palm["pose"][1] * k, palm["pose"][2]]
    for f in d["fingers"]:
        f["length"] *= k
        f["thickness"] *= k
        f["torque_limits"] = [t * k**3 for t in f["torque_limits"]]
    d["object"]["vertices"] = [[x * k, y * k] for x, y in d["object"]["vertices"]]
    if "mass" in d["object"]:
        d["object"]["mass"] *= k**2
    return d
