"""Sub-commands of ``zarco`` that live with the HIL tools (hil, replay, decode)."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add this package's sub-commands to the ``zarco`` parser."""
    return None
