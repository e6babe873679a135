"""fit_rbv_to_silhouette: a predicted RBV rescaled per layer to the photo's silhouette."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.crown.rbv_fit import fit_rbv_to_silhouette, rbv_layer_extents, silhouette_layer_extents
from treeform.structures import Camera, RadialBoundingVolume


def _camera():
    return Camera(240, 240, 35.0, (0.0, 4.0, 25.0), (0.0, 4.0, 0.0), (0.0, 1.0, 0.0))


def _silhouette(rbv, cam):
    """The mask of a volume: the union of its layers' extents over their rows."""
    mask = np.zeros((cam.height, cam.width), bool)
    cols = rbv_layer_extents(rbv, cam)
    edges = rbv.layer_edges()
    v = cam.project(np.array([[0.0, y, 0.0] for y in edges]))[:, 1]
    for i in range(rbv.n_layers):
        r0, r1 = int(round(v[i + 1])), int(round(v[i]))
        mask[r0:r1, int(round(cols[i, 0])):int(round(cols[i, 1]))] = True
    return mask


def test_a_volume_fitted_to_another_volumes_silhouette_spans_it():
    rng = np.random.default_rng(0)
    cam = _camera()
    true = RadialBoundingVolume(rng.uniform(1.0, 3.0, (8, 8)), 8.0)
    guess = RadialBoundingVolume(np.full((8, 8), 2.0), 8.0)
    mask = _silhouette(true, cam)
    fit = fit_rbv_to_silhouette(guess, cam, mask)
    target = silhouette_layer_extents(fit, cam, mask)
    got = rbv_layer_extents(fit, cam)
    before = np.abs(rbv_layer_extents(guess, cam) - target).max()
    assert np.abs(got - target).max() < 1.5 < before  # within a pixel and a half, from many pixels off
    # sectors facing the camera scale by the mean of their layer's left and right factors: no sector flips
    assert (fit.radii > 0).all() and fit.height == guess.height


def test_layers_the_mask_misses_keep_their_radii_and_bad_input_is_refused():
    cam = _camera()
    guess = RadialBoundingVolume(np.full((4, 4), 2.0), 8.0)
    mask = _silhouette(guess, cam)
    v = cam.project(np.array([[0.0, 4.0, 0.0]]))[0, 1]
    mask[:int(v)] = False  # the upper half of the tree is not in the photo
    fit = fit_rbv_to_silhouette(guess, cam, mask)
    np.testing.assert_allclose(fit.radii[2:], 2.0)
    with pytest.raises(InputError):
        fit_rbv_to_silhouette(guess, cam, mask[:10])
    with pytest.raises(InputError):
        fit_rbv_to_silhouette(guess, cam, mask, limits=(2.0, 3.0))
