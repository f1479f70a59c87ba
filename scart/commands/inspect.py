"""Placeholder: this group of verbs is not built yet."""

from __future__ import annotations

import argparse


def register(subparsers: argparse._SubParsersAction) -> None:  # noqa: SLF001
    """Add this group's verbs (none yet)."""
