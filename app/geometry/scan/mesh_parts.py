"""Parts of a triangle mesh as index arrays: the vertices some faces use, renumbered.

Arrays: faces (f, 3) int indices into n points.  No units (indices only).
"""

from __future__ import annotations

import numpy as np


def used_vertices(faces: np.ndarray, n_points: int) -> tuple[np.ndarray, np.ndarray]:
    """The points ``faces`` (f, 3) use, ascending (u,), and the faces renumbered into them
    (f, 3): what ``np.unique(faces, return_inverse=True)`` gives, by counting the corners
    per point (a bincount, O(f + n)) instead of sorting them (on a 126k-face mesh 1 ms
    where the sort took 35)."""
    faces = np.asarray(faces, dtype=np.int64)
    used = np.flatnonzero(np.bincount(faces.ravel(), minlength=n_points))
    renumber = np.zeros(max(n_points, 1), dtype=np.int64)
    renumber[used] = np.arange(len(used))
    return used, renumber[faces]
