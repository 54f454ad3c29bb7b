"""Reading YAML the user wrote (config files, environment overrides, model files) strictly.

PyYAML's safe loader executes no tag, but it builds nested values recursively (10 000 nested
brackets raise ``RecursionError``) and silently keeps the last of two equal keys. Here the
nesting depth is measured first on PyYAML's event stream (iterative) and limited to
``MAX_DEPTH``, and a mapping with a repeated key is refused; every problem is one
:class:`UserError` naming the input.
"""

from __future__ import annotations

from typing import Any

import yaml

from pipeline.errors import UserError

MAX_DEPTH = 64             # configs nest 4 levels; a model file 5


class _StrictLoader(yaml.SafeLoader):
    """SafeLoader refusing a mapping that repeats a key (merge keys ``<<`` excepted)."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen: dict[Any, Any] = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                if not isinstance(key, (str, int, float, bool)):
                    continue                       # an unhashable key: SafeLoader's own error follows
                if key in seen:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"duplicate key {key!r} (first on line {seen[key].line + 1})",
                        key_node.start_mark)
                seen[key] = key_node.start_mark
        return super().construct_mapping(node, deep=deep)


def _depth(text: str) -> int:
    depth = deepest = 0
    for event in yaml.parse(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader)):      # libyaml: fast
        if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
            depth += 1
            deepest = max(deepest, depth)
            if deepest > MAX_DEPTH:
                break
        elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            depth -= 1
    return deepest


def load_yaml(text: str, where: str) -> Any:
    """The value ``text`` holds; UserError naming ``where`` (a file, an environment variable) if it
    is not valid YAML, nests deeper than ``MAX_DEPTH`` or repeats a key."""
    try:
        if _depth(text) > MAX_DEPTH:
            raise UserError(f"{where}: nested deeper than {MAX_DEPTH} levels")
        return yaml.load(text, Loader=_StrictLoader)        # noqa: S506 (a SafeLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" (line {mark.line + 1})" if mark is not None else ""
        problem = (str(getattr(exc, "problem", None) or exc).strip().splitlines() or ["?"])[0]
        raise UserError(f"{where}: not valid YAML{line}: {problem}") from None
