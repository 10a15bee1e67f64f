"""The numerical core: a leg scan in, an exact NURBS calf, its measurements and a
stocking design out (numpy, scipy, scikit-learn and trimesh only; no web, no database).

Its sub-packages follow the pipeline - ``scan``, ``sections``, ``anatomy``, ``spline``,
``placement``, ``fit``, ``measures``, ``garment`` - and import one way, in that order
(README, "Layout"); :mod:`app.geometry.errors` is the one failure type of them all.
"""
