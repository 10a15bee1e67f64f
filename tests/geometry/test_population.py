"""Population statistics over lsq nets (point distribution model)."""

from __future__ import annotations

import numpy as np

from app.geometry.fit.pipeline import FitOptions, fit_scan
from app.geometry.measures.population import as_right_leg, distinct_net, girth_percentiles, population_of
from app.geometry.scan.reader import load_scan
from app.geometry.spline.lsq import LsqGrid, surface_from_net
from app.geometry.spline.nurbs import evaluate_grid
from tests.conftest import REAL


def _lsq_net():
    result = fit_scan(load_scan(REAL / "bodyparts3d_right_leg.stl"), FitOptions(mode="lsq", grid="7x15"))
    return distinct_net(result.surface), result.surface


def test_the_average_of_n_copies_of_one_record_is_that_record():
    net, surface = _lsq_net()
    model = population_of(np.stack([net] * 5))
    assert np.abs(model.mean_net - net).max() < 1e-9
    assert len(model.modes) == 0 and len(model.variance_share) == 0  # no variation at all
    average = surface_from_net(model.mean_net)
    u, v = np.linspace(0, 1, 30, endpoint=False), np.linspace(0, 1, 20)
    assert np.abs(evaluate_grid(average, u, v) - evaluate_grid(surface, u, v)).max() < 1e-9


def test_a_mirrored_left_leg_is_the_right_leg_again_and_keeps_the_front():
    net, surface = _lsq_net()
    left = net * np.array([-1.0, 1.0, 1.0])[None, None, :]  # the mirror image: a left leg ...
    left = left[(-np.arange(len(net))) % len(net)]  # ... whose u also runs counter-clockwise from the front
    assert np.allclose(as_right_leg(left), net)
    assert np.allclose(as_right_leg(net)[0], net[0] * np.array([-1.0, 1.0, 1.0]))  # column 0 stays in front


def test_modes_of_a_population_varying_in_two_known_ways():
    """Calves scaled around (girth) and stretched along (length) by independent amounts:
    two modes carry all the variance, the larger first; percentiles are the data's."""
    net, _ = _lsq_net()
    rng = np.random.default_rng(0)
    nets = []
    for _ in range(40):
        wide, long = 1.0 + 0.05 * rng.standard_normal(), 1.0 + 0.01 * rng.standard_normal()
        nets.append(net * np.array([wide, wide, long]))
    model = population_of(np.stack(nets))
    assert model.variance_share[:2].sum() > 0.999 and model.variance_share[0] > model.variance_share[1]
    assert model.sd_mm[0] > model.sd_mm[1] > 0
    values = np.arange(1.0, 101.0)
    assert girth_percentiles({"C": values})["C"]["p50"] == np.percentile(values, 50)


def test_grid_sizes_of_the_population_nets():
    net, _ = _lsq_net()
    assert net.shape == (LsqGrid(7, 15).around, LsqGrid(7, 15).along, 3)
