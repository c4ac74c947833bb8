"""Meshes: the :class:`Mesh` value object and the brick-wall generator."""

from .brick_wall import BrickWallLayout, brick_wall
from .mesh import INTERFACE_KINDS, Mesh

__all__ = ["Mesh", "INTERFACE_KINDS", "BrickWallLayout", "brick_wall"]
