"""Zonotope geometry of the wheel sets (from the shared layer).

The functions live in `adcs_common.zonotope`, shared with the thruster
duty QP (its attainable force and torque set); they are named here too.
"""

from adcs_common.zonotope import (
    gauge,
    radial_extent,
    zonotope_facets,
    zonotope_support,
)

__all__ = ["gauge", "radial_extent", "zonotope_facets", "zonotope_support"]
