"""Leaflet billboards (seed 001 §3.6, §4.2, Fig. 13): channels, consistency, determinism, errors."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from treeform._shared.errors import InputError
from treeform.methods.envelope.leaflets import leaflet_billboard, leaflet_volume


@pytest.fixture(scope="module", params=["sphere", "cone"])
def board(request, gl):
    return leaflet_billboard(request.param, size=96, attractors=200, seed=1)


def test_channels_agree(board):
    covered = board.rgba[..., 3] > 0
    assert 0.15 < covered.mean() < 0.9 and board.leaves > 10
    for ch in (board.normal, board.centroid, board.uv):
        assert ch.shape == (96, 96, 3) and (ch[~covered] == 0).all()
    assert ((board.type > 0) == covered).all() and set(np.unique(board.type)) <= {0, 128, 255}
    assert (board.type == 255).sum() > (board.type == 128).sum()  # mostly leaves
    n = board.normal[covered].astype(float) / 127.5 - 1.0
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=0.03)
    leaf = board.type[covered] == 255
    assert (n[leaf, 2] > -0.02).all()  # double-sided leaves: normals face the viewer
    assert board.ao[covered].min() < board.ao[covered].max() and (board.ao[~covered] == 0).all()
    assert board.depth.dtype == np.uint16 and board.depth[covered].min() < board.depth[covered].max()


def test_leaf_centroids_point_into_their_leaf(board):
    leaf = board.type == 255
    cx = board.centroid[..., 0].astype(float) / 255 * 96
    cy = board.centroid[..., 1].astype(float) / 255 * 96
    rows, cols = np.nonzero(leaf)
    d = np.hypot(cx[leaf] - cols - 0.5, cy[leaf] - rows - 0.5)
    assert np.median(d) < 96 * 0.12  # a pixel's centroid is its leaf's centre, nearby
    assert len(np.unique(board.centroid[leaf][:, :2], axis=0)) > 5  # many leaves, many centroids


def test_deterministic_and_seeded(gl):
    a = leaflet_billboard("cone", size=64, attractors=100, seed=3)
    b = leaflet_billboard("cone", size=64, attractors=100, seed=3)
    c = leaflet_billboard("cone", size=64, attractors=100, seed=4)
    assert all((getattr(a, k) == getattr(b, k)).all() for k in ("rgba", "normal", "centroid", "uv", "ao", "depth"))
    assert not (a.rgba == c.rgba).all()


def test_volumes():
    contains, (lo, hi), root, _ = leaflet_volume("cone")
    assert contains(np.array([[0, 0.1, 0], [0, 1.9, 0.5], [0, 2.1, 0]])).tolist() == [True, False, False]
    assert contains(root[None])[0]
    with pytest.raises(InputError, match="shape"):
        leaflet_volume("cube")


def test_outputs_and_user_leaflet(tmp_path, gl):
    leaf = np.zeros((32, 16, 4), np.uint8)
    leaf[4:28, 3:13] = (200, 40, 40, 255)
    Image.fromarray(leaf).save(tmp_path / "red.png")
    b = leaflet_billboard("sphere", size=64, attractors=100, leaflet=tmp_path / "red.png", out=tmp_path / "o")
    names = {p.name for p in (tmp_path / "o").iterdir()}
    assert names == {"rgba.png", "normal.png", "centroid.png", "uv.png", "ao.png", "depth.png", "type.png",
                     "channels.png", "leaflets.json"}
    assert np.asarray(Image.open(tmp_path / "o" / "depth.png")).dtype == np.uint16
    leaves = b.rgba[b.type == 255]
    assert np.median(leaves[:, 0]) > 170 and np.median(leaves[:, 1]) < 70  # the leaflet's own colours


def test_bad_inputs(tmp_path, gl):
    with pytest.raises(InputError, match="shape"):
        leaflet_billboard("cube")
    with pytest.raises(InputError, match="size"):
        leaflet_billboard(size=10)
    Image.fromarray(np.zeros((32, 32, 4), np.uint8)).save(tmp_path / "empty.png")
    with pytest.raises(InputError, match="transparent"):
        leaflet_billboard(leaflet=tmp_path / "empty.png", size=64)
