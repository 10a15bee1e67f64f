"""Polar resampling of mesh and point-cloud sections (paper section 2.1)."""

import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull

from app.geometry.fit.calf import inner_wall_warning
from app.geometry.sections import (
    edge_crossings,
    mesh_section_segments,
    neighbour_edges,
    polygon_perimeter,
    ray_angles,
    slice_mesh_polar,
    tape_band_girths,
    tape_girths,
)
from app.geometry.sections.cloud import slice_points_polar
from app.geometry.sections.cloud_edges import round_edge_crossings
from app.geometry.sections.mesh import inner_contour_share
from app.geometry.sections.polar import star_hull_perimeters
from benchmarks.corpus.makehuman import ansur_subjects, leg_submesh, sized_legs
from tests.phantoms import cylinder, tube_mesh


def test_cylinder_sections_have_the_true_radius_and_centre():
    mesh = cylinder(50.0, 50.0)
    offset = np.array([3.0, -4.0, 0.0])
    sections = slice_mesh_polar(mesh.vertices + offset, mesh.faces, np.linspace(5, 295, 200))
    assert sections.valid.all() and np.all(sections.coverage == 1.0)
    assert np.allclose(sections.centroids_mm, offset[:2], atol=1e-6)
    # 256-gon: the radius along a ray lies between r cos(pi/256) and r
    assert sections.radii_mm.min() >= 50 * np.cos(np.pi / 256) - 1e-9 and sections.radii_mm.max() <= 50 + 1e-9
    # 72-gon chord perimeter (paper section 3.2) of a circle
    expected = 72 * 2 * 50 * np.sin(np.pi / 72)
    assert np.allclose(sections.circumferences(), expected, rtol=1e-4)


def test_a_hole_in_the_mesh_is_bridged_in_the_polar_domain():
    mesh = cylinder(45.0, 45.0)
    centres = mesh.triangles_center
    angle = np.arctan2(centres[:, 1], centres[:, 0])
    keep = ~((np.abs(angle - 1.0) < 0.35) & (np.abs(centres[:, 2] - 150) < 30))  # a 40 degree x 60 mm hole
    sections = slice_mesh_polar(mesh.vertices, mesh.faces[keep], np.array([150.0]))
    assert sections.coverage[0] < 1.0
    assert sections.valid.all()
    assert np.abs(sections.radii_mm - 45).max() < 0.5


def test_a_hole_in_a_meshs_flat_side_is_read_along_the_leg_not_round_the_section():
    """An oval tube (semi-axes 55 + 0.05 z by 40 mm, its flat sides at +-y) with a hole 70
    degrees wide and 40 mm tall in a flat side.  Sliced every 2 mm, the rays through the
    hole are read between the sections above and below it (AXIAL_FILL_SPAN_MM): the
    girths within 0.3 mm of the whole tube's.  One plane sliced alone has nothing above or
    below it: read round the section, the straight line in angle across the flat side
    misses it by millimetres.  A hole taller than AXIAL_FILL_SPAN_MM is read round the
    section as before."""
    heights = np.arange(0.0, 302.0, 2.0)
    whole = tube_mesh(heights, 55.0 + 0.05 * heights, np.full(len(heights), 40.0))
    centres = whole.triangles_center
    angle = np.arctan2(centres[:, 1] / 40.0, centres[:, 0] / (55.0 + 0.05 * centres[:, 2]))
    in_flat_side = np.abs(angle - np.pi / 2) < np.radians(35.0)
    planes = np.arange(101.0, 200.0, 2.0)
    intact = slice_mesh_polar(whole.vertices, whole.faces, planes).circumferences()
    for tall_mm, along in ((40.0, True), (80.0, False)):
        faces = whole.faces[~(in_flat_side & (np.abs(centres[:, 2] - 150.0) < tall_mm / 2))]
        sections = slice_mesh_polar(whole.vertices, faces, planes)
        holed = sections.coverage < 1.0
        assert holed.sum() >= tall_mm / 2 - 2 and sections.valid.all()
        error = np.abs(sections.circumferences() - intact)[holed]
        if along:
            assert error.max() < 0.3
        else:  # read round the section
            assert error.max() > 1.0
    alone = slice_mesh_polar(whole.vertices, whole.faces[~(in_flat_side & (np.abs(centres[:, 2] - 150.0) < 20.0))],
                             np.array([151.0]))
    assert alone.coverage[0] < 1.0 and abs(alone.circumferences()[0] - intact[25]) > 1.0


def _ridged_tube(heights: np.ndarray, n_around: int = 256) -> trimesh.Trimesh:
    """A tube (n, 3 vertices; faces between rings) whose rings of radius 45 + 0.05 z mm
    carry a ridge along the leg at 90 degrees, 6 mm high and about 35 degrees wide (a
    tendon's or the shin's crest), open at both ends."""
    theta = np.linspace(0.0, 2.0 * np.pi, n_around, endpoint=False)
    r = 45.0 + 0.05 * heights[:, None] + 6.0 * np.exp(-(((theta[None, :] - np.pi / 2) / 0.3) ** 2))
    rings = np.stack([r * np.cos(theta), r * np.sin(theta), np.broadcast_to(heights[:, None], r.shape)], axis=-1)
    i, j = np.meshgrid(np.arange(len(heights) - 1), np.arange(n_around), indexing="ij")
    a, b = i * n_around + j, i * n_around + (j + 1) % n_around
    c, d = b + n_around, a + n_around
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return trimesh.Trimesh(rings.reshape(-1, 3), faces, process=False)


def test_a_tape_across_a_hole_in_a_meshs_ridge_reads_the_skin_along_the_leg():
    """A hole 40 mm tall over the ridge (70 degrees of the section): a tape's girth at
    planes through the hole is read with the rays through the hole taken along the leg
    (sections_across_holes), within 0.3 mm of the whole tube's; the fit round the
    section's points alone knows nothing of the ridge in the hole and reads it short."""
    heights = np.arange(0.0, 302.0, 2.0)
    whole = _ridged_tube(heights)
    centres = whole.triangles_center
    in_hole = (np.abs(np.arctan2(centres[:, 1], centres[:, 0]) - np.pi / 2) < np.radians(35.0)) & (
        np.abs(centres[:, 2] - 150.0) < 20.0)
    planes = np.array([135.0, 143.0, 151.0, 159.0, 165.0])
    intact = tape_girths(whole.vertices, whole.faces, planes)
    assert np.abs(tape_girths(whole.vertices, whole.faces[~in_hole], planes) - intact).max() < 0.3
    plane, seg = mesh_section_segments(whole.vertices, whole.faces[~in_hole], planes)
    ends = np.column_stack([seg.reshape(-1, 2), np.repeat(planes[plane], 2)])
    round_the_section = slice_points_polar(ends, planes, 360, half_thickness=1e-6, widen=False).tape_perimeters()
    assert (intact - round_the_section).min() > 1.0


def test_noisy_point_cloud_is_fitted_across_gaps():
    """Ellipse 55 x 40 mm, 0.3 mm noise, a 34 degree strip never scanned."""
    rng = np.random.default_rng(0)
    theta = rng.uniform(0, 2 * np.pi, 200_000)
    theta = theta[~((theta > 2.0) & (theta < 2.6))]
    z = rng.uniform(0, 300, theta.size)
    pts = np.stack([55 * np.cos(theta), 40 * np.sin(theta), z], axis=1) + rng.normal(0, 0.3, (theta.size, 3))
    sections = slice_points_polar(pts, np.linspace(20, 280, 50))
    assert sections.valid.all()
    assert np.abs(sections.centroids_mm).max() < 0.5
    angles = ray_angles(72)
    true_r = 1.0 / np.sqrt((np.cos(angles) / 55) ** 2 + (np.sin(angles) / 40) ** 2)
    error = np.abs(sections.radii_mm - true_r)
    in_gap = (angles > 1.75) & (angles < 2.85)  # the strip and 10 degrees either side
    assert error[:, ~in_gap].max() < 0.3  # noise averaged out where there are points
    assert error[:, in_gap].max() < 1.0  # bridged smoothly where there are none


def _open_tube(radius: float, heights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A round tube of ``radius`` mm over ``heights`` (k,), its ends open: vertices, faces."""
    tube = tube_mesh(heights, np.full(len(heights), radius), np.full(len(heights), radius))
    sides = tube.faces[(tube.faces < len(heights) * 256).all(axis=1)]  # the caps' faces name the centres
    return np.asarray(tube.vertices), sides


def test_a_wall_inside_the_skin_is_no_part_of_the_tape():
    """A mesh hollowed for 3D printing: the skin (a tube of radius 50 mm) and a wall 3 mm
    inside it, joined at both open ends by rims (one connected surface, as a solidify
    gives it).  The tape reads the skin's girth, not a mix of both walls (it read 2 pi x
    1.5 mm short of it), and the skin alone reads the same; the calf fit says the mesh
    holds the wall."""
    heights = np.arange(0.0, 301.0, 2.0)
    skin, faces = _open_tube(50.0, heights)
    wall = skin * np.array([47.0 / 50.0, 47.0 / 50.0, 1.0])
    n = len(skin)
    ring = np.arange(256)
    rims = [np.column_stack([end + (ring + 1) % 256, end + ring, end + ring + n]) for end in (0, n - 256)]
    rims += [np.column_stack([end + (ring + 1) % 256, end + ring + n, end + (ring + 1) % 256 + n]) for end in (0, n - 256)]
    shell_faces = np.vstack([faces, faces[:, ::-1] + n, *rims])
    shell = np.vstack([skin, wall])
    at = np.array([60.0, 150.0, 240.0])
    alone = tape_girths(skin, faces, at)
    assert np.allclose(alone, 2 * np.pi * 50.0, rtol=1e-3)
    assert np.allclose(tape_girths(shell, shell_faces, at), alone, atol=1e-6)
    # the wall's length against the skin's, section by section: the calf fit's warning
    assert np.allclose(inner_contour_share(shell, shell_faces, at), 47.0 / 50.0, atol=0.01)
    assert np.allclose(inner_contour_share(skin, faces, at), 0.0)
    assert inner_wall_warning(skin, faces, 20.0, 280.0) == []
    assert "second surface inside the skin" in inner_wall_warning(shell, shell_faces, 20.0, 280.0)[0]
    # a hole in the skin leaves its arcs outermost where they face out: still the skin's girth
    centres = skin[faces].mean(axis=1)
    hole = (np.arctan2(centres[:, 1], centres[:, 0]) > 0.5) & (np.arctan2(centres[:, 1], centres[:, 0]) < 1.0)
    holed = faces[~(hole & (np.abs(centres[:, 2] - 150.0) < 20.0))]
    assert abs(tape_girths(skin, holed, np.array([150.0]))[0] - alone[1]) < 1.0


def test_polygon_perimeter_of_a_square_in_polar_form():
    angles = np.array([0, 0.5, 1.0, 1.5]) * np.pi
    assert np.isclose(polygon_perimeter(np.ones(4), angles), 4 * np.sqrt(2))


def test_elongation_of_a_circle_an_ellipse_and_a_missing_section():
    """sqrt of the principal second moments' ratio of the ray ends: 1 for a circle,
    sqrt(a/b) for an a x b ellipse on equal-angle rays from its centre, whatever its
    turn; NaN for a missing section."""
    from app.geometry.sections import PolarSections

    angles = ray_angles(72)

    def ellipse(a, b, turn=0.0):
        t = angles - turn
        return a * b / np.sqrt((b * np.cos(t)) ** 2 + (a * np.sin(t)) ** 2)

    radii = np.stack([np.full(72, 40.0), ellipse(44.0, 40.0), ellipse(80.0, 40.0, 0.7), np.full(72, np.nan)])
    sections = PolarSections(np.arange(4.0), np.zeros((4, 2)), radii, angles, np.ones(4))
    elongation = sections.elongations()
    assert np.allclose(elongation[:3], [1.0, np.sqrt(1.1), np.sqrt(2.0)], atol=1e-6)
    assert np.isnan(elongation[3])


def test_a_missing_section_is_bridged_from_closed_neighbours_within_reach_only():
    """bridge_sections: an open row between closed rows 4 mm below and 6 mm above takes
    their radii and centroid in proportion (40 -> 50 mm: 44); one whose nearest closed
    row below is 12 mm away (over LAYER_BRIDGE_MM) and one with none above stay open;
    closed rows are left as they are."""
    from app.geometry.sections import PolarSections
    from app.geometry.sections.polar import bridge_sections

    angles = ray_angles(72)
    heights = np.array([0.0, 4.0, 10.0, 22.0, 30.0])
    radii = np.stack([np.full(72, 40.0), np.full(72, np.nan), np.full(72, 50.0), np.full(72, np.nan), np.full(72, np.nan)])
    centres = np.array([[0.0, 0.0], [np.nan, np.nan], [10.0, -5.0], [np.nan, np.nan], [np.nan, np.nan]])
    sections = PolarSections(heights, centres, radii, angles, np.ones(5))
    bridged = bridge_sections(sections, sections)
    assert np.allclose(bridged.radii_mm[1], 44.0) and np.allclose(bridged.centroids_mm[1], [4.0, -2.0])
    assert not bridged.valid[3] and not bridged.valid[4]
    assert np.array_equal(bridged.radii_mm[[0, 2]], radii[[0, 2]])


def test_a_tape_band_outvotes_one_spoiled_plane():
    """A tube of radius 45 mm with a 2 mm ridge standing out to 55 mm 4 mm above the
    height read (a fold, a seam of two scanner views): the plane through the ridge reads
    the ridge, the band of five planes across a tape's width reads the leg."""
    z = np.arange(0.0, 300.01, 0.25)
    radius = 45.0 + 10.0 * np.exp(-(((z - 154.0) / 1.0) ** 2))
    leg = tube_mesh(z, radius, radius)
    heights = np.array([150.0])
    assert tape_girths(leg.vertices, leg.faces, heights + 4.0)[0] > 2 * np.pi * 54.0
    assert tape_band_girths(leg.vertices, leg.faces, heights)[0] == pytest.approx(2 * np.pi * 45.0, rel=2e-3)
    # away from the ridge, the band reads what one plane reads
    assert tape_band_girths(leg.vertices, leg.faces, heights - 50.0)[0] == pytest.approx(
        tape_girths(leg.vertices, leg.faces, heights - 50.0)[0], rel=1e-6)
    # no section in any plane of the band: NaN
    assert np.isnan(tape_band_girths(leg.vertices, leg.faces, np.array([1000.0]))[0])
    # the band only half on the leg: only the planes whose mirror has a section count -
    # none at 301 mm (the tube ends at 300), the middle plane alone at 299
    assert np.isnan(tape_band_girths(leg.vertices, leg.faces, np.array([301.0]))[0])
    assert tape_band_girths(leg.vertices, leg.faces, np.array([299.0]))[0] == pytest.approx(
        tape_girths(leg.vertices, leg.faces, np.array([299.0]))[0], rel=1e-9)


def test_star_hull_perimeters_are_scipys_convex_hulls():
    """Bumpy, dented and noisy star-shaped contours on 36-360 rays: the perimeter of
    each one's convex hull, as scipy's ConvexHull (its 2-D area) gives it."""
    rng = np.random.default_rng(3)
    for n_rays in (36, 72, 360):
        angles = ray_angles(n_rays)
        radii = 40 + 3 * np.sin(3 * angles + rng.uniform(0, 6, (60, 1))) + rng.normal(0, 0.6, (60, n_rays))
        radii[:20] += 8 * np.exp(-(((angles - 1.0) / 0.1) ** 2))  # a sharp bump the hull spans
        radii[20:40] -= 8 * np.exp(-(((angles - 2.0) / 0.2) ** 2))  # a hollow it bridges
        expected = [ConvexHull(np.column_stack([r * np.cos(angles), r * np.sin(angles)])).area for r in radii]
        assert np.allclose(star_hull_perimeters(radii, angles), expected, rtol=0, atol=1e-9)
    circle = star_hull_perimeters(np.full((1, 360), 50.0), ray_angles(360))[0]
    assert circle == pytest.approx(2 * 360 * 50 * np.sin(np.pi / 360), abs=1e-9)  # a 360-gon


def test_a_clouds_section_is_the_same_read_alone_or_with_other_heights():
    """A section of a cloud depends on its own slab only: read alone, or in one call with
    heights below and above it (whose slabs come first in the concatenated points), it
    has the same centre and radii (to rounding) - so a point's girth does not change with what else
    is measured in the same call."""
    rng = np.random.default_rng(11)
    n = 60_000
    z = rng.uniform(0.0, 300.0, n)
    theta = rng.uniform(0.0, 2 * np.pi, n)
    radius = 45.0 + 0.05 * z + 4.0 * np.cos(2 * theta) + rng.normal(0.0, 0.6, n)  # a noisy, tapering oval
    cloud = np.column_stack([3.0 + radius * np.cos(theta), -2.0 + radius * 1.2 * np.sin(theta), z])
    alone = slice_points_polar(cloud, np.array([151.3]), 360)
    for others in ([23.0, 151.3], [12.5, 40.0, 151.3, 230.0], [151.3, 260.0], [99.1, 101.7, 151.3]):
        together = slice_points_polar(cloud, np.array(others), 360)
        row = others.index(151.3)
        # to rounding (batched sums add in another order): 1e-9 mm
        np.testing.assert_allclose(together.centroids_mm[row], alone.centroids_mm[0], rtol=0, atol=1e-9)
        np.testing.assert_allclose(together.radii_mm[row], alone.radii_mm[0], rtol=0, atol=1e-9)
        assert abs(together.tape_perimeters()[row] - alone.tape_perimeters()[0]) < 1e-9


def test_a_sparse_clouds_neighbour_graph_crosses_a_slanted_plane_on_the_skin():
    """A cylinder of radius 40 mm sampled at 2,500 random points (the graph's edges 7.4
    mm long, median), its axis tilted 50 degrees from z: the plane z = 0 cuts it in an
    ellipse, at a slant.  The crossings of the 10-nearest-neighbour graph lie within a
    chord's sagitta of the skin (measured: 0.04 mm median, 0.44 max) and their hull is the
    ellipse's perimeter within 1% (0.2%); the points of a slab an edge thick, projected,
    spread across the skin's run through the slab (+8%)."""
    rng = np.random.default_rng(2)
    angle, along = rng.uniform(0.0, 2 * np.pi, 2_500), rng.uniform(-150.0, 150.0, 2_500)
    tilt = np.radians(50.0)
    axis, across = np.array([np.sin(tilt), 0.0, np.cos(tilt)]), np.array([np.cos(tilt), 0.0, -np.sin(tilt)])
    side = np.array([0.0, 1.0, 0.0])
    points = (along[:, None] * axis + 40.0 * np.cos(angle)[:, None] * across + 40.0 * np.sin(angle)[:, None] * side)
    edges = neighbour_edges(points)
    assert len(edges) == len(np.unique(edges, axis=0)) and (edges[:, 0] < edges[:, 1]).all()
    plane, crossings = edge_crossings(points, edges, np.array([-50.0, 0.0]))
    on_plane = np.column_stack([crossings[plane == 1], np.zeros((plane == 1).sum())])
    off_axis = np.linalg.norm(on_plane - np.outer(on_plane @ axis, axis), axis=1)  # distance from the cylinder's axis
    assert np.median(np.abs(off_axis - 40.0)) < 0.2 and np.abs(off_axis - 40.0).max() < 1.0
    a, b = 40.0 / np.cos(tilt), 40.0
    h = ((a - b) / (a + b)) ** 2
    ellipse = np.pi * (a + b) * (1 + 3 * h / (10 + np.sqrt(4 - 3 * h)))  # Ramanujan's, 1e-5 relative here
    assert ConvexHull(crossings[plane == 1]).area == pytest.approx(ellipse, rel=0.01)
    spacing = float(np.median(np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)))
    slab = points[np.abs(points[:, 2]) < spacing]
    assert ConvexHull(slab[:, :2]).area > 1.03 * ellipse
    assert not len(neighbour_edges(points[:1]))



def test_a_sparse_clouds_tape_girths_are_read_on_its_neighbour_graph():
    """A generated adult's left leg (ANSUR II subject 2000, benchmarks.corpus.makehuman)
    subdivided once, its 6.5k vertices as a cloud (a body mesh's vertices: 8 points per
    mm of height, sparse by app.geometry.fit.sparse_clouds.SPARSE_CLOUD_POINTS_PER_MM), and
    60 tape planes from the ankle to the thigh: read where the neighbour graph's edges
    cross them (interpolated round the section's centre), every girth is read and the
    same leg's mesh's within 1.5 mm p95 (0.7 measured); read on the slabs such a cloud
    needs, at least a millimetre further off (p95 5.2, and 4 of the 60 planes not read).  A graph's sections are read at ascending heights."""
    legs = sized_legs(ansur_subjects()[2000], np.random.default_rng(4), subdivisions=1)
    leg = leg_submesh(legs.vertices, legs.faces, 1.0)
    points = leg.vertices[:, [0, 2, 1]] * [1.0, -1.0, 1.0]  # the model stands along +y: z up
    low, high = points[:, 2].min(), points[:, 2].max()
    heights = np.linspace(low + 0.08 * (high - low), low + 0.85 * (high - low), 60)
    mesh = tape_girths(points, leg.faces, heights)
    on_graph = np.abs(tape_girths(points, None, heights, neighbour_edges(points)) - mesh)
    on_slabs = np.abs(tape_girths(points, None, heights) - mesh)
    assert np.isfinite(on_graph).all() and np.percentile(on_graph, 95) < 1.5
    assert np.nanpercentile(on_slabs, 95) > np.percentile(on_graph, 95) + 1.0
    with pytest.raises(ValueError, match="ascending"):
        tape_girths(points, None, heights[::-1], neighbour_edges(points))


def test_round_crossings_lie_on_a_round_section_where_the_chords_cut_inside():
    """A cylinder of radius 35 mm (an ankle) sampled as a coarse tessellation's vertices:
    12 points per ring, rings 12 mm apart, each turned by half a step, so the edges
    between rings (15 mm) span 15 degrees.  Crossings interpolated round the plane's
    centre lie on the circle; linear ones up to the chord's sagitta (0.30 mm) inside."""
    rings = np.arange(0.0, 96.0, 12.0)
    angle = np.linspace(0.0, 2 * np.pi, 12, endpoint=False)[None, :] + (np.pi / 12) * (np.arange(len(rings)) % 2)[:, None]
    points = np.column_stack([(35.0 * np.cos(angle)).ravel(), (35.0 * np.sin(angle)).ravel(), np.repeat(rings, 12)])
    edges = neighbour_edges(points, neighbours=4)
    heights = np.array([30.0, 42.0, 54.5])
    _, linear = edge_crossings(points, edges, heights)
    plane, rounded = round_edge_crossings(points, edges, heights)
    assert len(rounded) == len(linear) and np.bincount(plane, minlength=3).min() >= 24
    np.testing.assert_allclose(np.linalg.norm(rounded, axis=1), 35.0, atol=1e-6)
    inside = 35.0 - np.linalg.norm(linear, axis=1)
    assert inside.max() == pytest.approx(35.0 * (1 - np.cos(np.pi / 24)), abs=0.01) and inside.min() >= -1e-9
