"""Names every stage of the billboard cloud shares."""

from __future__ import annotations

FRONT, REAR, INTERIOR, TRUNK = 0, 1, 2, 3
"""Billboard layers of :attr:`Placement.layer`."""
