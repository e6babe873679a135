"""The silhouette's growth form and the RGBA normalisation it reads (treeform.contour.form / .normalize)."""

import numpy as np
import pytest

from treeform._shared.errors import InputError, NoTreeFoundError
from treeform.contour import classify_form, form_descriptor, normalize_rgba


def _rgba(mask: np.ndarray) -> np.ndarray:
    out = np.zeros(mask.shape + (4,), np.uint8)
    out[mask] = (40, 90, 40, 255)
    return out


def _round_crown(h=300, w=260) -> np.ndarray:
    yy, xx = np.mgrid[:h, :w]
    crown = ((xx - w / 2) / (0.45 * w)) ** 2 + ((yy - 0.35 * h) / (0.33 * h)) ** 2 <= 1
    stem = (np.abs(xx - w / 2) <= 6) & (yy >= 0.35 * h) & (yy < h - 5)
    return crown | stem


def _cone(h=240, w=140) -> np.ndarray:
    yy, xx = np.mgrid[:h, :w]
    return (np.abs(xx - w / 2) <= 0.28 * yy) & (yy < h - 12) | (np.abs(xx - w / 2) <= 3) & (yy < h - 4)


def test_normalised_tree_stands_on_the_bottom_margin_centred():
    m = np.zeros((200, 400), bool)
    m[50:150, 30:90] = True  # off-centre, wider canvas than the tree
    out = normalize_rgba(_rgba(m), size=128)
    assert out.shape == (128, 128, 4) and out.dtype == np.uint8
    ys, xs = np.nonzero(out[..., 3] >= 128)
    margin = 128 // 64
    assert ys.max() == 127 - margin and ys.min() == margin  # the taller side fills the inner square
    assert abs((xs.min() + xs.max()) / 2 - 63.5) <= 1
    assert (out[out[..., 3] < 128] == 0).all()


def test_forms_of_drawn_silhouettes_at_any_size():
    assert classify_form(_rgba(_cone())) == "conifer"
    assert classify_form(_rgba(_round_crown())) == "broadleaf"
    # the form is a property of the shape, not of the picture's size or placement
    big = np.zeros((700, 500), bool)
    big[100:580, 80:360] = np.kron(_cone(), np.ones((2, 2), bool))
    assert classify_form(_rgba(big)) == "conifer"
    d = form_descriptor(_rgba(_round_crown()))
    assert d.stem > 0.2 and d.aspect > 0.9 and 0 <= d.widest <= 1
    assert set(d.to_dict()) == {"stem", "aspect", "widest", "width15", "width30", "radiality", "hub"}


def test_bad_inputs_name_the_problem():
    with pytest.raises(InputError):
        classify_form(np.zeros((20, 20, 3), np.uint8))
    with pytest.raises(InputError):
        normalize_rgba(np.zeros((20, 20, 4), np.float32))
    with pytest.raises(NoTreeFoundError):
        classify_form(np.zeros((20, 20, 4), np.uint8))
