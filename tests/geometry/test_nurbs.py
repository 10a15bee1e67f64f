"""B-spline machinery against independent references (scipy, dense algebra, finite differences)."""

import numpy as np
import pytest
from scipy.interpolate import BSpline

from app.geometry.spline.basis import BSplineBasis
from app.geometry.spline.nurbs import (
    NurbsSurface,
    chord_length_parameters,
    evaluate_derivatives,
    evaluate_grid,
    hartley_judd_knots,
    interpolate_closed_cubic,
    periodic_knot_vector,
    surface_from_layers,
)


def _layers(m=15, seed=0):
    rng = np.random.default_rng(seed)
    theta = np.sort(rng.uniform(0, 2 * np.pi, m))
    out = []
    for z in (0.0, 40.0, 80.0, 130.0, 190.0, 240.0, 280.0):
        r = 40 + 0.08 * z + 3 * np.sin(3 * theta + z / 50)
        out.append(np.stack([r * np.cos(theta), 1.2 * r * np.sin(theta), np.full(m, z)], axis=1))
    return np.array(out)


def test_a_basis_is_a_partition_of_unity_with_degree_plus_one_functions_per_point():
    knots = np.array([0, 0, 0, 0, 0.1, 0.35, 0.5, 0.8, 1, 1, 1, 1.0])
    basis = BSplineBasis(knots, 3)
    u = np.linspace(0, 1, 101)
    columns, values = basis.local(u)
    assert basis.n_functions == 8 and basis.domain == (0.0, 1.0)
    assert columns.shape == values.shape == (101, 4)
    assert np.allclose(values.sum(axis=1), 1.0) and (values >= 0).all()
    dense = basis.design_matrix(u).toarray()
    for i in range(8):  # each column is the i-th basis function, N_i = BSpline with e_i
        assert np.allclose(dense[:, i], BSpline(knots, np.eye(8)[i], 3)(u), atol=1e-12)


@pytest.mark.parametrize("knots,periodic,rule", [
    ([0, 0, 0, 0, 0.5, 0.4, 1, 1, 1, 1], False, "non-decreasing"),
    ([0, 0, 0, 0, 0, 0, 0, 0], False, "empty domain"),
    ([0, 0, 0, 0, 0.5, 0.5, 0.5, 0.5, 1, 1, 1, 1], False, "repeats more than 3"),
    ([0, 0, 0, 0.2, 0.5, 1, 1, 1, 1], False, "clamped"),
    ([-0.3, -0.2, -0.1, 0.0, 0.1, 0.5, 1.0, 1.1, 1.2, 1.3], True, "repeat every"),
    ([0, 0, 0, 0, np.nan, 1, 1, 1, 1], False, "finite"),
])
def test_a_basis_refuses_knots_that_break_its_contract(knots, periodic, rule):
    with pytest.raises(ValueError, match=rule):
        BSplineBasis(np.array(knots, dtype=float), 3, periodic)


def test_a_surface_checks_its_net_against_its_knots():
    layers = _layers()
    surface = surface_from_layers(layers)
    assert surface.basis_u.periodic and not surface.basis_v.periodic
    with pytest.raises(ValueError, match="control net"):
        NurbsSurface(3, 3, surface.knots_u, surface.knots_v, surface.control_points[:-1], surface.weights[:-1])
    with pytest.raises(ValueError, match="positive"):
        NurbsSurface(3, 3, surface.knots_u, surface.knots_v, surface.control_points, -surface.weights)
    with pytest.raises(ValueError, match="repeat every"):  # periodic claimed, clamped u knots given
        NurbsSurface(3, 3, np.r_[np.zeros(3), np.linspace(0, 1, len(surface.knots_u) - 6), np.ones(3)],
                     surface.knots_v, surface.control_points, surface.weights)


def test_closed_interpolation_passes_through_points_and_is_c2_closed():
    layers = _layers()
    params = chord_length_parameters(layers, closed=True).mean(axis=0)
    control = interpolate_closed_cubic(layers, params)
    knots = periodic_knot_vector(params, 3)
    for layer, ctrl in zip(layers, control):
        spline = BSpline(knots, ctrl, 3)
        assert np.allclose(spline(params[:-1]), layer, atol=1e-9)
        # closed: value and first two derivatives agree across the seam u=0 / u=1
        for k in range(3):
            d = spline.derivative(k) if k else spline
            assert np.allclose(d(0.0), d(1.0), atol=1e-6 * (1 + np.abs(d(0.0)).max()))


def test_hartley_judd_knots_are_clamped_and_increasing():
    polygon = np.cumsum(np.random.default_rng(2).uniform(1, 5, size=(7, 3)), axis=0)
    knots = hartley_judd_knots(polygon, 3)
    assert knots.shape == (11,)
    assert np.all(knots[:4] == 0) and np.all(knots[-4:] == 1)
    assert np.all(np.diff(knots) >= 0) and np.all(np.diff(knots[3:8]) > 0)


@pytest.mark.parametrize("mode", ["paper", "paper_stacked"])
def test_surface_layout_is_standard_open_form(mode):
    layers = _layers()
    s = surface_from_layers(layers, mode=mode)
    nu, nv = s.shape
    assert (nu, nv) == (15 + 3, 7)
    assert len(s.knots_u) == nu + 4 and len(s.knots_v) == nv + 4
    assert np.allclose(s.control_points[:3], s.control_points[-3:])
    assert s.domain_u == (0.0, 1.0) and s.domain_v == (0.0, 1.0)
    # the same surface evaluated by scipy as a plain (non-periodic) tensor product
    u, v = np.linspace(0, 1, 9), np.linspace(0, 1, 5)
    grid = evaluate_grid(s, u, v)
    along_u = BSpline(s.knots_u, np.transpose(s.control_points, (0, 1, 2)).reshape(nu, -1), 3)(u).reshape(len(u), nv, 3)
    reference = BSpline(s.knots_v, np.transpose(along_u, (1, 0, 2)), 3)(v)  # (len(v), len(u), 3)
    assert np.allclose(grid, np.transpose(reference, (1, 0, 2)), atol=1e-9)


def test_paper_mode_interpolates_every_feature_point_stacked_only_the_ends():
    layers = _layers()
    pu = chord_length_parameters(layers, closed=True).mean(axis=0)[:-1]
    columns = np.transpose(layers, (1, 0, 2))
    pv = chord_length_parameters(columns, closed=False).mean(axis=0)
    s = surface_from_layers(layers, mode="paper")
    grid = evaluate_grid(s, pu, pv)
    assert np.allclose(np.transpose(grid, (1, 0, 2)), layers, atol=1e-8)
    stacked = surface_from_layers(layers, mode="paper_stacked")
    ends = evaluate_grid(stacked, pu, np.array([0.0, 1.0]))
    assert np.allclose(ends[:, 0], layers[0], atol=1e-8) and np.allclose(ends[:, 1], layers[-1], atol=1e-8)
    middle = evaluate_grid(stacked, pu, pv[3:4])[:, 0]
    assert np.abs(middle - layers[3]).max() > 0.01  # the literal reading does not pass through


@pytest.mark.parametrize("rational", [False, True])
def test_derivatives_match_finite_differences(rational):
    """Both paths: weights all 1 (polynomial shortcut) and random weights (eq. 4.20)."""
    layers = _layers()
    s = surface_from_layers(layers)
    if rational:
        weights = 1.0 + 0.3 * np.random.default_rng(3).uniform(size=s.weights.shape)
        weights[-3:] = weights[:3]
        s = NurbsSurface(3, 3, s.knots_u, s.knots_v, s.control_points, weights, True)
    rng = np.random.default_rng(4)
    u, v = rng.uniform(0.05, 0.95, 50), rng.uniform(0.05, 0.95, 50)
    h = 1e-6
    pt, su, sv, suu, suv, svv = evaluate_derivatives(s, u, v)
    direct = np.array([evaluate_grid(s, u[i : i + 1], v[i : i + 1])[0, 0] for i in range(5)])
    assert np.allclose(pt[:5], direct, atol=1e-9)
    fu = (evaluate_derivatives(s, u + h, v)[0] - evaluate_derivatives(s, u - h, v)[0]) / (2 * h)
    fv = (evaluate_derivatives(s, u, v + h)[0] - evaluate_derivatives(s, u, v - h)[0]) / (2 * h)
    assert np.allclose(su, fu, rtol=1e-4, atol=1e-3)
    assert np.allclose(sv, fv, rtol=1e-4, atol=1e-3)
    fuu = (evaluate_derivatives(s, u + h, v)[1] - evaluate_derivatives(s, u - h, v)[1]) / (2 * h)
    fuv = (evaluate_derivatives(s, u, v + h)[1] - evaluate_derivatives(s, u, v - h)[1]) / (2 * h)
    fvv = (evaluate_derivatives(s, u, v + h)[2] - evaluate_derivatives(s, u, v - h)[2]) / (2 * h)
    assert np.allclose(suu, fuu, rtol=1e-3, atol=1e-1)
    assert np.allclose(suv, fuv, rtol=1e-3, atol=1e-1)
    assert np.allclose(svv, fvv, rtol=1e-3, atol=1e-1)
