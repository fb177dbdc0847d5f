"""Random convex polygons for hypothesis, shared by the tippability and width tests."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from hypothesis import assume
from hypothesis import strategies as st
from scipy.spatial import ConvexHull, QhullError


@st.composite
def random_hulls(
    draw,
    max_points: int,
    aspects: tuple[float, float],
    scatter: Callable[[np.random.Generator, int, float], np.ndarray],
) -> np.ndarray:
    """The convex hull (counter-clockwise vertices) of 3 to ``max_points`` random points,
    ``scatter(rng, count, aspect)`` with an aspect drawn from ``aspects``; a flat point set is
    rejected."""
    n = draw(st.integers(3, max_points))
    seed = draw(st.integers(0, 2**32 - 1))
    aspect = draw(st.floats(*aspects))
    pts = scatter(np.random.default_rng(seed), n, aspect)
    try:
        return pts[ConvexHull(pts).vertices]
    except QhullError:
        assume(False)
