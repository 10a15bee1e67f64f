"""Cross-sections of a scan resampled on a polar grid (paper section 2.1).

:mod:`~app.geometry.sections.polar` holds the type (:class:`PolarSections`) and its
plane geometry; :mod:`~app.geometry.sections.mesh` slices a mesh exactly (plane-section
segments, rays from the centroid), :mod:`~app.geometry.sections.cloud` a point cloud
(robust polar fits of slabs); :mod:`~app.geometry.sections.cloud_edges` reads a cloud's
plane sections on its neighbour graph (the foot's oblique loops, a sparse cloud's tape
girths); :mod:`~app.geometry.sections.loop_smoothing` moves a section's points onto the
curve they sample (moving least squares) before its tape is read.  :func:`slice_polar`
and :func:`tape_girths` choose between mesh and cloud.  Units: mm.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from app.geometry.sections.cloud import group_median, slice_points_polar
from app.geometry.sections.cloud_edges import crossing_ends, edge_crossings, neighbour_edges, round_edge_crossings
from app.geometry.sections.limb_graph import LimbGraph, limb_crossings, limb_graph
from app.geometry.sections.loop_smoothing import project_on_local_quadratics
from app.geometry.sections.mesh import holed_sections, mesh_section_segments, sections_across_holes, slice_mesh_polar
from app.geometry.sections.polar import PolarSections, largest_gap, polygon_centroid, polygon_perimeter, ray_angles

__all__ = ["TAPE_BAND_OFFSETS_MM", "LimbGraph", "PolarSections", "crossing_ends", "edge_crossings", "graph_sections",
           "group_median", "largest_gap", "limb_crossings", "limb_graph", "mesh_section_segments", "neighbour_edges",
           "polygon_centroid", "polygon_perimeter", "project_on_local_quadratics", "ray_angles", "slice_mesh_polar",
           "slice_points_polar", "slice_polar", "tape_band_girths", "tape_girths", "tape_sections"]

#: a tape measure is a band about a centimetre wide, not a plane: a landmark's girth is
#: read over the planes TAPE_BAND_OFFSETS_MM from it (mm) and the median taken.  At a
#: waist or the calf maximum the girth changes only to second order across +-4 mm
#: (~0.1 mm on the corpus legs' profiles), on B1's slope linearly (the median is the
#: middle plane's value), while one section spoiled by a hole's edge, a stray slab or a
#: noisy contour - which a single plane reads whole - is outvoted by the other four.
TAPE_BAND_OFFSETS_MM = np.array([-4.0, -2.0, 0.0, 2.0, 4.0])


def tape_girths(points: np.ndarray, faces: np.ndarray | None, heights: np.ndarray,
                edges: np.ndarray | LimbGraph | None = None) -> np.ndarray:
    """Tape girths (k,) at ``heights`` (k,): the perimeter of the convex hull of the
    section, which is what a tape measure (ANSUR, the hosiery standards) reads, mm
    (:func:`tape_sections`' perimeters); NaN where there is no section."""
    return tape_sections(points, faces, heights, edges).tape_perimeters()


def tape_sections(points: np.ndarray, faces: np.ndarray | None, heights: np.ndarray,
                  edges: np.ndarray | LimbGraph | None = None) -> PolarSections:
    """The sections a tape is read on at ``heights`` (k,), mm: points (n, 3) in the frame
    whose z the heights are, faces (f, 3) or None; their ``tape_perimeters()`` are the
    tape girths, their centroids where the tape's plane crosses the limb's axis.

    The hull is taken of the robust polar fit of the section on 360 rays
    (:mod:`app.geometry.sections.cloud`): of the exact plane-section segment ends for a
    mesh; for a cloud with its neighbour graph ``edges`` (e, 2)
    (:func:`app.geometry.sections.cloud_edges.neighbour_edges`: a sparse cloud's, whose
    slabs would be thick), of where the graph's edges cross the plane, and else of the
    slab of points - so scanner noise on the vertices, which the hull of the raw section
    would pick up at its outermost points, is averaged out; a :class:`LimbGraph`'s
    edges along the limb cross the planes on the skin's bend along it
    (:func:`app.geometry.sections.limb_graph.limb_crossings`).  NaN rows where there is
    no section.  With ``edges``, the heights ascend.
    """
    heights = np.asarray(heights, dtype=np.float64)
    if faces is not None and len(faces):
        plane, seg = mesh_section_segments(points, faces, heights, outer_only=True)
        sections = _on_planes(seg.reshape(-1, 2), np.repeat(plane, 2), heights, 360)
        holed = holed_sections(plane, seg, len(heights))
        if not holed.any():
            return sections
        # a hole's rays read along the leg (sections_across_holes): round the section the
        # fit's curve cuts across it as a chord does, short of the skin by up to 3 mm of
        # girth where a hole sits on the ankle's flat (chart_accuracy 8 11, leg 3 holes)
        radii, centroids = sections.radii_mm.copy(), sections.centroids_mm.copy()
        centroids[holed], radii[holed] = sections_across_holes(points, faces, heights[holed], 360)
        return dataclasses.replace(sections, radii_mm=radii, centroids_mm=centroids)
    if isinstance(edges, LimbGraph):
        return graph_sections(points, edges, heights, 360)
    if edges is not None:
        _check_ascending(heights)
        plane, crossings = round_edge_crossings(points, edges, heights)
        return _on_planes(crossings, plane, heights, 360)
    return slice_points_polar(points, heights, 360)


def graph_sections(points: np.ndarray, graph: LimbGraph, heights: np.ndarray, n_angles: int = 72) -> PolarSections:
    """A sparse cloud's sections at ``heights`` (k,), ascending, read where its neighbour
    ``graph``'s edges cross each plane (:func:`app.geometry.sections.limb_graph.limb_crossings`),
    as a mesh's triangles are cut, instead of on a slab of points: the robust polar fit
    of the crossings on ``n_angles`` rays.  points (n, 3) mm in the frame whose z the
    heights are; NaN rows where the crossings leave the section open."""
    heights = np.asarray(heights, dtype=np.float64)
    _check_ascending(heights)
    plane, crossings = limb_crossings(points, graph, heights)
    return _on_planes(crossings, plane, heights, n_angles)


def _check_ascending(heights: np.ndarray) -> None:
    """ValueError unless ``heights`` (k,) ascend: a cloud's crossings are matched to
    their planes by a sorted search."""
    if np.any(np.diff(heights) < 0):
        raise ValueError("a cloud's sections on its neighbour graph are read at ascending heights")


def _on_planes(xy: np.ndarray, plane: np.ndarray, heights: np.ndarray, n_angles: int) -> PolarSections:
    """The robust polar fit of points ``xy`` (m, 2) mm lying on the planes ``heights``
    (k,) (``plane`` (m,) each one's): no slab round them, none widened."""
    return slice_points_polar(np.column_stack([xy, heights[plane]]), heights, n_angles, half_thickness=1e-6,
                              widen=False)


def tape_band_girths(points: np.ndarray, faces: np.ndarray | None, heights: np.ndarray,
                     edges: np.ndarray | LimbGraph | None = None) -> np.ndarray:
    """Tape girths (k,) at ``heights`` (k,) read across a tape's width: the median of
    :func:`tape_girths` on the planes :data:`TAPE_BAND_OFFSETS_MM` about each height
    (a plane without a section is left out, and so is its mirror about the height),
    mm; NaN where no mirrored pair (or the middle plane) has a section: the caller then
    reads the girth some other way.
    points (n, 3) mm in the frame whose z the heights are; faces (f, 3) or None; a
    cloud's neighbour graph ``edges`` (e, 2) or None (:func:`tape_sections`)."""
    heights = np.asarray(heights, dtype=np.float64)
    planes = (heights[:, None] + TAPE_BAND_OFFSETS_MM[None, :]).ravel()
    order = np.argsort(planes, kind="stable")
    flat = np.empty(len(planes))
    flat[order] = tape_girths(points, faces, planes[order], edges)
    girths = flat.reshape(len(heights), len(TAPE_BAND_OFFSETS_MM))
    # a band read on one side only is not a reading at the height (on B1's slope, a
    # sparse cloud measured only 4 mm above B1 reads its girth 4 mm up): only the planes
    # whose mirror about the height is measured too count
    symmetric = np.isfinite(girths) & np.isfinite(girths[:, ::-1])
    measured = symmetric.any(axis=1)
    out = np.full(len(heights), np.nan)
    out[measured] = np.nanmedian(np.where(symmetric, girths, np.nan)[measured], axis=1)
    return out


def slice_polar(
    points: np.ndarray, faces: np.ndarray | None, heights: np.ndarray, n_angles: int = 72, recentre: bool = True
) -> PolarSections:
    """Dispatch to :func:`slice_mesh_polar` or
    :func:`app.geometry.sections.cloud.slice_points_polar`."""
    if faces is not None and len(faces):
        return slice_mesh_polar(points, faces, heights, n_angles, recentre)
    return slice_points_polar(points, heights, n_angles)
