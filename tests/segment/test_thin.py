"""Thin dark lines: the tubeness filter and the ridges it keeps."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.segment.thin import thin_dark_lines, tubeness


@pytest.mark.parametrize("sigmas", [(1.0, 1.5), (0.8,), (2.0, 3.0)])
def test_tubeness_is_scikit_images_sato(sigmas):
    from skimage.filters import sato

    rng = np.random.default_rng(0)
    grey = rng.random((60, 80)).astype(np.float32)
    grey[:, 30] *= 0.2  # a dark line in the noise
    ref = sato(grey, sigmas=list(sigmas), black_ridges=True)
    out = tubeness(grey, sigmas)
    assert out.shape == grey.shape and out.dtype == np.float32
    np.testing.assert_allclose(out, ref, atol=2e-6)


def test_thin_dark_lines_keeps_twigs_against_the_sky_near_the_tree():
    img = np.full((64, 64, 3), 210, np.uint8)
    img[40:, 20:44] = (60, 90, 40)          # the crown's lower lobe
    img[4:10, 24:40] = (60, 90, 40)         # and its top
    img[10:40, 31] = (50, 40, 30)           # a twig between them, one pixel wide, against the sky
    img[4:60, 2] = (50, 40, 30)             # a pole far from the tree
    near = np.zeros((64, 64), bool)
    near[40:, 20:44] = near[4:10, 24:40] = True
    sky = img[..., 2] > 200
    m = thin_dark_lines(img, near, against=sky, margin=8)
    assert m[12:36, 30:33].any(axis=1).all()      # the twig, all along
    assert not m[:, :8].any()                     # not the pole
    with pytest.raises(InputError, match="near"):
        thin_dark_lines(img, near[:10])
    assert not thin_dark_lines(img, np.zeros((64, 64), bool)).any()
