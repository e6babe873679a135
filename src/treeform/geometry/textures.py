"""A tree's texture set: the foliage kind's texture and texture sizes chosen from the tree's size.

Bark UVs span one branch circumference per texture tile (:func:`~treeform.geometry.branch_mesh`)
and a leaf card spans the whole leaf texture (:func:`~treeform.geometry.leaf_cards`), so the
texel density on the tree is the texture edge over the trunk's circumference, or over the card
size. :func:`texture_sizes` picks the power of two nearest to :data:`TEXELS_PER_METRE` on the
trunk and on the median card, never below the defaults (512² bark, 256² leaves) nor, unless
asked for, above 1024².
"""

from __future__ import annotations

import math

import numpy as np

from treeform._shared.checks import check_choice, check_int
from treeform._shared.errors import InputError
from treeform.structures.foliage import Foliage
from treeform.structures.skeleton import TreeSkeleton

__all__ = ["BARK_TEXTURE_SIZE", "FOLIAGE_KINDS", "LEAF_TEXTURE_SIZE", "MAX_AUTO_TEXTURE_SIZE", "TEXELS_PER_METRE",
           "bark_normals", "tint_texture", "foliage_coverage", "foliage_texture_kind", "texture_sizes", "tree_textures"]

FOLIAGE_KINDS = ("broadleaf", "needles", "scales")
"""Foliage kinds: broadleaf clusters, pine-like needle clusters, thuja-like scale sprays."""

BARK_TEXTURE_SIZE = 512
"""Default (and smallest automatic) bark texture edge in texels."""
LEAF_TEXTURE_SIZE = 256
"""Default (and smallest automatic) leaf texture edge in texels."""
MAX_AUTO_TEXTURE_SIZE = 1024
"""Largest edge :func:`texture_sizes` chooses by itself (``texture_size`` may ask for more)."""
TEXELS_PER_METRE = 512.0
"""Target texel density on the trunk (per metre of circumference) and on a leaf card."""

_TEXTURE_KIND = {"broadleaf": "cluster", "needles": "needles", "scales": "scales"}


def foliage_texture_kind(foliage_kind: str) -> str:
    """The :func:`~treeform.geometry.leaf_texture` kind drawn for a foliage kind.

    Examples
    --------
    >>> foliage_texture_kind("broadleaf"), foliage_texture_kind("needles")
    ('cluster', 'needles')
    """
    check_choice(foliage_kind, "foliage", FOLIAGE_KINDS)
    return _TEXTURE_KIND[foliage_kind]


def foliage_coverage(foliage_kind: str, *, seed: int = 0) -> float:
    """Opaque fraction of a foliage kind's leaf texture (256², this seed), for sizing cards.

    A broadleaf cluster is drawn to :data:`~treeform.geometry.leaves.CLUSTER_COVERAGE` (0.65)
    exactly; needle clusters and scale sprays cover about 0.3 of their card, so a method
    that sizes its cards for a crown coverage enlarges them by ``sqrt(0.65 / coverage)``.

    Examples
    --------
    >>> foliage_coverage("broadleaf"), 0.2 < foliage_coverage("needles") < 0.45
    (0.65, True)
    """
    from treeform.geometry import leaves as _leaves

    kind = foliage_texture_kind(foliage_kind)
    if kind == "cluster":
        return _leaves.CLUSTER_COVERAGE
    return _leaves.texture_coverage(_leaves._default_leaf(LEAF_TEXTURE_SIZE, int(seed), kind))


def _nearest_pow2(x: float, lo: int, hi: int) -> int:
    """The power of two nearest to ``x`` (in log scale), clipped to [lo, hi]."""
    p = 2 ** int(round(math.log2(max(float(x), 1.0))))
    return int(min(max(p, lo), hi))


def texture_sizes(skeleton: TreeSkeleton, foliage: Foliage | None = None, *, texture_size=None) -> tuple[int, int]:
    """Edge lengths in texels of the bark and leaf textures of a tree.

    With ``texture_size`` N: bark N², leaves (N/2)². Without: the bark edge is the power of
    two nearest to ``TEXELS_PER_METRE · 2π · r_max`` (the trunk's circumference; ``r_max`` is
    the skeleton's largest radius) and the leaf edge the one nearest to
    ``TEXELS_PER_METRE · median card size``, clipped to [512, 1024] and [256, 1024].

    Parameters
    ----------
    skeleton : TreeSkeleton
    foliage : Foliage, optional
        The leaf cards (None or empty: the default leaf size).
    texture_size : int, optional
        Bark edge N in [16, 8192]; the leaves get N // 2.

    Returns
    -------
    bark, leaves : int

    Examples
    --------
    >>> s = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0.]]), np.array([-1, 0]), np.array([0.35, 0.3]))
    >>> texture_sizes(s), texture_sizes(s, texture_size=2048)
    ((1024, 256), (2048, 1024))
    """
    if not isinstance(skeleton, TreeSkeleton):
        raise InputError(f"skeleton: expected a TreeSkeleton, got {type(skeleton).__name__}")
    if texture_size is not None:
        n = check_int(texture_size, "texture_size", 16, 8192)
        return n, n // 2
    r = float(np.max(skeleton.radius)) if skeleton.n_nodes else 0.0
    bark = _nearest_pow2(TEXELS_PER_METRE * 2.0 * math.pi * r, BARK_TEXTURE_SIZE, MAX_AUTO_TEXTURE_SIZE)
    leaves = LEAF_TEXTURE_SIZE
    if foliage is not None and len(foliage):
        leaves = _nearest_pow2(TEXELS_PER_METRE * float(np.median(foliage.size)), LEAF_TEXTURE_SIZE,
                               MAX_AUTO_TEXTURE_SIZE)
    return bark, leaves


def tree_textures(skeleton: TreeSkeleton, foliage: Foliage | None = None, *, foliage_kind: str = "broadleaf",
                  texture_size=None, seed=0) -> tuple[np.ndarray, np.ndarray]:
    """The bark and leaf textures of a tree, sized by :func:`texture_sizes`.

    Parameters
    ----------
    skeleton : TreeSkeleton
    foliage : Foliage, optional
    foliage_kind : {"broadleaf", "needles", "scales"}
        Leaf texture: a broadleaf cluster, a needle cluster or a scale spray.
    texture_size : int, optional
        See :func:`texture_sizes`.
    seed : int
        Same seed -> identical textures.

    Returns
    -------
    bark : ndarray, shape (B, B, 4), uint8
    leaves : ndarray, shape (L, L, 4), uint8
    """
    from treeform.geometry import leaves as _leaves
    from treeform.geometry import tubes as _tubes

    kind = foliage_texture_kind(foliage_kind)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise InputError(f"seed: expected an integer, got {seed!r}")
    bark_size, leaf_size = texture_sizes(skeleton, foliage, texture_size=texture_size)
    return _tubes._default_bark(bark_size, int(seed)).copy(), _leaves._default_leaf(leaf_size, int(seed), kind).copy()


def bark_normals(bark: np.ndarray, *, seed=0) -> np.ndarray:
    """The normal map of the bark texture :func:`tree_textures` made (its size, this seed).

    Examples
    --------
    >>> s = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0.]]), np.array([-1, 0]), np.array([0.1, 0.05]))
    >>> bark, _ = tree_textures(s)
    >>> bark_normals(bark).shape == bark.shape
    True
    """
    from treeform.geometry import tubes as _tubes

    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise InputError(f"seed: expected an integer, got {seed!r}")
    bark = np.asarray(bark)
    if bark.ndim != 3 or bark.shape[0] != bark.shape[1]:
        raise InputError(f"bark: expected a square (N, N, 4) texture, got shape {bark.shape}")
    return _tubes._default_bark_normal(int(bark.shape[0]), int(seed)).copy()


def tint_texture(texture: np.ndarray, rgb) -> np.ndarray:
    """The texture with its colour scaled per channel so its mean becomes ``rgb`` (0-255).

    Each channel's gain is kept within [0.2, 3] (a texture darker or lighter than the photo's
    wood by more than that keeps some of its own look); alpha is unchanged.

    Examples
    --------
    >>> t = np.full((4, 4, 4), 100, np.uint8)
    >>> tint_texture(t, (150, 100, 50))[0, 0].tolist()
    [150, 100, 50, 100]
    """
    t = np.asarray(texture)
    if t.ndim != 3 or t.shape[2] not in (3, 4) or t.dtype != np.uint8:
        raise InputError(f"texture: expected an (H, W, 3|4) uint8 array, got {t.shape} {t.dtype}")
    target = np.asarray(rgb, np.float64).reshape(-1)
    if target.shape != (3,) or not np.all(np.isfinite(target)):
        raise InputError(f"rgb: expected 3 numbers, got {rgb!r}")
    mean = t[..., :3].reshape(-1, 3).mean(0)
    gain = np.clip(target / np.maximum(mean, 1e-3), 0.2, 3.0)
    out = t.copy()
    out[..., :3] = np.clip(np.rint(t[..., :3] * gain), 0, 255).astype(np.uint8)
    return out
