"""Mutations of a scenario tree (parsed YAML) for the hostile-input tests and the reliability corpus
(``benchmarks/reliability_corpus.py``)."""

from __future__ import annotations

import copy
from typing import Any


def key_paths(tree: Any, path: tuple = ()) -> list[tuple]:
    """Every key path of a tree (mappings and lists), the tree itself excluded."""
    out = []
    if isinstance(tree, dict):
        items = list(tree.items())
    elif isinstance(tree, list):
        items = list(enumerate(tree))
    else:
        return out
    for key, value in items:
        out.append((*path, key))
        out += key_paths(value, (*path, key))
    return out


def mutate(tree: dict[str, Any], path: tuple, op: str, value: Any) -> dict[str, Any]:
    """A copy of the tree with the value at ``path`` replaced, deleted, or given an unknown sibling."""
    out = copy.deepcopy(tree)
    node = out
    for part in path[:-1]:
        node = node[part]
    last = path[-1]
    if op == "replace":
        node[last] = value
    elif op == "delete":
        del node[last]
    elif isinstance(node, dict):
        node["unknown_key_" + str(last)] = value
    else:
        node.append(value)
    return out
