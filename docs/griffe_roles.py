"""A Griffe extension for the API reference: the docstrings' Sphinx roles as links.

physrover's docstrings cross-reference with Sphinx roles (``:func:`step_team```,
``:class:`~physrover.domain.plan.StepPlan```), which mkdocstrings prints raw. Once the
package is loaded, this rewrites every role into an autorefs link
(``<autoref identifier="physrover.domain.step.step_team" optional>``): the target resolved
as Python would from the docstring's scope (the object, its parents, its module, the
module's imports), shown as the role shows it (``~`` keeps the last name). A name outside
physrover (numpy, gymnasium) stays code, unlinked. ``optional``: a target the reference
does not render (a private helper) prints as code instead of failing the strict build;
``tests/test_docs.py`` checks that no role is left and no physrover target goes unlinked.

Used by ``mkdocs.yml`` (``plugins: mkdocstrings: handlers: python: options: extensions``).
"""

from __future__ import annotations

import html
import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?(mod|func|class|meth|data|attr|exc|obj|const|type):`([^`]+)`")
"""A Sphinx role: its kind and its target (``~a.b``, ``a.b``, ``.b`` or ``text <a.b>``)."""


def _member(root: griffe.Object, names: list[str]) -> griffe.Object | None:
    """``root``'s member at the dotted ``names``, following imports; None if there is none."""
    obj: Any = root
    for name in names:
        try:
            obj = obj.members[name]
            if obj.is_alias:
                obj = obj.final_target
        except (KeyError, griffe.AliasResolutionError, griffe.CyclicAliasError):
            return None
    return obj


def index(package: griffe.Module) -> dict[str, list[str]]:
    """Every object of ``package`` (aliases left out) by its own name: name -> paths."""
    paths: dict[str, list[str]] = {}

    def visit(obj: Any) -> None:
        paths.setdefault(obj.name, []).append(obj.path)
        for member in obj.members.values():
            if not member.is_alias:
                visit(member)

    visit(package)
    return paths


def resolve(target: str, scope: griffe.Object, package: griffe.Module,
            names_index: dict[str, list[str]] | None = None) -> str | None:  # fmt: skip
    """The full path of ``target`` as seen from ``scope`` (the object whose docstring names
    it): a full ``physrover.`` path; a name found in the scope, one of its parents or its
    module (imports followed); else the one object of the package with that name (from
    ``names_index``, :func:`index`: a docstring may name what its module does not import).
    None outside the package, or where the name is ambiguous."""
    names = target.lstrip(".").split(".")
    if names[0] == package.name:
        found = _member(package, names[1:])
        return found.path if found is not None else None
    node: Any = scope
    while node is not None:
        found = _member(node, names)
        if found is not None and found.path.startswith(package.name + "."):
            return found.path
        node = node.parent
    candidates = (names_index or {}).get(names[0], [])
    if len(candidates) == 1:
        found = _member(package, [*candidates[0].split(".")[1:], *names[1:]])
        return found.path if found is not None else None
    return None


def _link(kind: str, target: str, scope: griffe.Object, package: griffe.Module,
          names_index: dict[str, list[str]], unresolved: list) -> str:  # fmt: skip
    """One role as an autorefs link, or as code where its target is outside physrover (then
    noted in ``unresolved`` with the docstring's object)."""
    explicit = re.fullmatch(r"(.*?)\s*<([^>]+)>", target)  # ``text <target>``
    if explicit:
        shown, target = explicit.group(1), explicit.group(2)
    else:
        shown = target.lstrip("~.").rsplit(".", 1)[-1] if target.startswith("~") else \
            target.lstrip(".")  # fmt: skip
    target = target.lstrip("~")
    if kind in ("func", "meth") and not explicit:
        shown += "()"
    path = resolve(target, scope, package, names_index)
    code = f"<code>{html.escape(shown)}</code>"
    if path is None:
        unresolved.append((scope.path, target))
        return code
    return f'<autoref identifier="{path}" optional>{code}</autoref>'


Unresolved = list[tuple[str, str]]
"""Roles left unlinked: (the docstring's object, the target)."""


def rewrite(text: str, scope: griffe.Object, package: griffe.Module,
            names_index: dict[str, list[str]], unresolved: Unresolved) -> str:  # fmt: skip
    """``text`` (a docstring) with every Sphinx role replaced (:func:`_link`)."""
    return ROLE.sub(lambda m: _link(m.group(1), m.group(2), scope, package, names_index,
                                    unresolved), text)  # fmt: skip


class SphinxRoles(griffe.Extension):
    """Rewrites the roles of every docstring of the package once it is loaded; the targets
    left unlinked (outside the package) are in ``unresolved``, (object path, target)."""

    def __init__(self) -> None:
        super().__init__()
        self.unresolved: Unresolved = []

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        seen: set[int] = set()
        names_index = index(pkg)

        def visit(obj: Any) -> None:
            if id(obj) in seen or obj.is_alias:
                return
            seen.add(id(obj))
            if obj.docstring is not None:
                obj.docstring.value = rewrite(obj.docstring.value, obj, pkg, names_index,
                                              self.unresolved)  # fmt: skip
            for member in obj.members.values():
                visit(member)

        visit(pkg)
