"""The modules a source file imports, read from its syntax tree (for the layering tests)."""

from __future__ import annotations

import ast
from pathlib import Path

from support import ROOT

__all__ = ["imports_of"]


def imports_of(path: Path, *, top_level_only: bool = False) -> list[str]:
    """Every module named by an import statement of ``path`` (relative ones resolved
    against its package under the repository's root); lazy and annotation-only ones too,
    unless ``top_level_only``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = ".".join(path.relative_to(ROOT).parent.parts)
    nodes = tree.body if top_level_only else list(ast.walk(tree))
    names: list[str] = []
    for node in nodes:
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level:
            base = ".".join(package.split(".")[:len(package.split(".")) - node.level + 1])
            names.append(f"{base}.{node.module}" if node.module else base)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.append(node.module)
    return names
