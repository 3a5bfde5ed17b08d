"""Nested dicts and lists as flat ``{"a/0/b": leaf}`` maps and back: how a learner's nested
state (a fitness method's) is stored beside flat arrays in a checkpoint."""

from __future__ import annotations


def flatten(tree, prefix: str = "") -> dict:
    """Nested dicts/lists -> {"a/0/b": leaf}."""
    if isinstance(tree, dict):
        items = tree.items()
    elif isinstance(tree, list):
        items = ((str(i), v) for i, v in enumerate(tree))
    else:
        return {prefix: tree}
    out = {}
    for key, value in items:
        out.update(flatten(value, f"{prefix}/{key}" if prefix else str(key)))
    return out


def unflatten(flat: dict):
    """The inverse of :func:`flatten`: {"a/0/b": leaf} -> nested dicts, a dict whose keys
    are 0..n-1 as a list."""
    root: dict = {}
    for key, value in flat.items():
        node = root
        *parents, leaf = key.split("/")
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = value

    def listify(node):
        if not isinstance(node, dict):
            return node
        if node and all(k.isdigit() for k in node):
            return [listify(node[str(i)]) for i in range(len(node))]
        return {k: listify(v) for k, v in node.items()}

    return listify(root)


__all__ = ["flatten", "unflatten"]
