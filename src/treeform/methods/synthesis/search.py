"""Analysis by synthesis (seed 004 §5): candidate proposals, the reprojection score, best of N.

Each candidate is a choice of the generative model's random variables — the number of
first-order branches n, the skeletonisation's cut draw, the leaf density and the leaf
distribution — made into a 3D tree, rendered from the photo's camera as a silhouette and
scored by eq. (3). The kept model maximises eq. (4): p(M) p(I | M) with p(I | M) = 1 - error
and p(M) the species prior on n.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from treeform.methods.synthesis.config import LEAF_DENSITIES, LEAF_SPREADS, SPECIES_PRIORS

__all__ = ["Proposal", "propose", "prior", "choose", "SilhouetteScorer", "best_so_far"]

_SKELETON_DRAWS = 3
"""Distinct cut draws (skeletonisation seeds) the proposals use for each n."""


@dataclass(frozen=True)
class Proposal:
    """One candidate's random variables (seed 004 §5: branches, cuts, leaf distribution, density)."""

    n_branches: int
    cut_seed: int
    density: float
    spread: float
    leaf_seed: int
    skeleton: str = "foliage"
    """Where the 2D skeleton comes from: "foliage" (§3: the outline's cuts, ``n_branches`` of
    them) or "wood" (the visible wood's shortest-path tree: its branches are observed, so
    ``n_branches`` is 0 and the species prior on n does not apply)."""

    def to_dict(self) -> dict:
        return asdict(self)


ERROR_SCALE = 0.02
"""Likelihood p(I | M) = exp(-error / ERROR_SCALE) in eq. (4): 2 points more of eq. (3) error
cost as much as a factor e^-1 of the prior (n about 1.4 standard deviations from its mean), so
the prior breaks near-ties without overruling a clearly better fit."""


def score(error: float, n_branches: int, species: str, *, observed: bool = False) -> float:
    """Log of eq. (4)'s posterior up to a constant: ``log p(M) - error / ERROR_SCALE``.

    ``observed``: the branches were read off the photo's wood, not drawn from the prior, so
    p(M) is the prior's peak (1) whatever their number.

    Examples
    --------
    >>> score(0.05, 6, "oak") > score(0.09, 6, "oak") and score(0.05, 6, "oak") > score(0.05, 9, "oak")
    True
    """
    pm = 1.0 if observed else prior(n_branches, species)
    return math.log(max(pm, 1e-300)) - float(error) / ERROR_SCALE


def prior(n_branches: int, species: str) -> float:
    """p(M) of eq. (4): the species' Gaussian on the number of first-order branches (peak 1)."""
    mean, sd, _ = SPECIES_PRIORS[species]
    return math.exp(-0.5 * ((n_branches - mean) / sd) ** 2)


def propose(count: int, species: str, *, n_branches: int | None = None, seed: int = 0,
            wood: bool = False) -> list[Proposal]:
    """``count`` distinct proposals, the first the prior's most likely model.

    The first proposal is the "single model" of Fig. 13 (n at the prior's mean, the first cut
    draw, middle density and spread). The others draw n from the species' Gaussian (or keep
    ``n_branches``), one of a few cut draws per n, and a leaf density and distribution from
    :data:`~treeform.methods.synthesis.config.LEAF_DENSITIES` / ``LEAF_SPREADS``; repeats are
    skipped, so every proposal is a different model. ``wood``: the photo shows its branches,
    so every second proposal after the first takes the wood skeleton instead of the foliage's
    cuts (with its own density and distribution draws).

    Examples
    --------
    >>> ps = propose(5, "oak", seed=0)
    >>> len(ps), ps[0].n_branches, ps[0].density, len(set(ps))
    (5, 6, 9.0, 5)
    >>> [p.skeleton for p in propose(5, "oak", seed=0, wood=True)]
    ['foliage', 'wood', 'foliage', 'wood', 'foliage']
    """
    mean, sd, _ = SPECIES_PRIORS[species]
    first_n = n_branches if n_branches is not None else int(round(mean))
    mid_d, mid_s = LEAF_DENSITIES[len(LEAF_DENSITIES) // 2], LEAF_SPREADS[len(LEAF_SPREADS) // 2]
    foliage = _draws(count, np.random.default_rng([seed, 4004]), first=(first_n, 0, mid_d, mid_s),
                     n=lambda r: n_branches if n_branches is not None else int(np.clip(round(r.normal(mean, sd)), 2, 14)))
    if not wood:
        return foliage
    # the wood skeleton is one: its depth draw and the leaves vary (own generator: the foliage
    # proposals stay the first ones of the search without wood)
    n_wood = min(count // 2, len(LEAF_DENSITIES) * len(LEAF_SPREADS) * _SKELETON_DRAWS)
    woods = [Proposal(0, p.cut_seed, p.density, p.spread, p.leaf_seed, skeleton="wood")
             for p in _draws(n_wood, np.random.default_rng([seed, 4005]), n=lambda r: 0)]
    out = []
    for k in range(count):
        take = woods if (k % 2 == 1 and woods) else foliage
        out.append(take.pop(0))
    return out


def _draws(count: int, rng: np.random.Generator, *, n, first=None) -> list[Proposal]:
    """``count`` distinct (n, cut draw, density, spread) proposals, ``first`` first when given."""
    out, seen = [], set()
    if first is not None:
        out.append(Proposal(*first, 0))
        seen.add(first)
    tries = 0
    while len(out) < count and tries < 50 * count:
        tries += 1
        key = (n(rng), int(rng.integers(_SKELETON_DRAWS)), float(rng.choice(LEAF_DENSITIES)),
               float(rng.choice(LEAF_SPREADS)))
        if key in seen:
            continue
        seen.add(key)
        out.append(Proposal(*key, leaf_seed=int(rng.integers(2**31))))
    return out


def choose(candidates: list) -> dict:
    """The kept model among scored candidates (dicts with ``skeleton``, ``score``, ``error``, ``index``).

    Within each skeleton source the highest eq. (4) score wins (the species prior on n
    regularises the foliage proposals' drawn n); between the foliage's and the wood's winners,
    the lower eq. (3) error (the wood's branches are observed, not drawn: no prior to weigh
    against), the foliage's on a tie.

    Examples
    --------
    >>> cs = [{"index": 0, "skeleton": "foliage", "score": -5.0, "error": 0.06},
    ...       {"index": 1, "skeleton": "wood", "score": -4.0, "error": 0.08}]
    >>> choose(cs)["index"]
    0
    """
    best = {}
    for c in candidates:
        b = best.get(c["skeleton"])
        if b is None or (c["score"], -c["index"]) > (b["score"], -b["index"]):
            best[c["skeleton"]] = c
    return min(best.values(), key=lambda c: (c["error"], c["skeleton"] != "foliage", c["index"]))


def best_so_far(errors) -> list:
    """Fig. 13's curve: the lowest error among the first k tested models, for k = 1..N."""
    return np.minimum.accumulate(np.asarray(errors, np.float64)).tolist() if len(errors) else []


class SilhouetteScorer:
    """Eq. (3) of candidate meshes, rendered from the photo's camera at ``height`` pixels.

    Parameters
    ----------
    camera : Camera
        The photo's camera (full size).
    mask : ndarray, shape (H, W), bool
        The photo's tree silhouette B.
    height : int
        Render height; the camera keeps its field of view, the mask is reduced by area
        (a pixel is tree when at least half of it is).
    """

    def __init__(self, camera, mask: np.ndarray, *, height: int = 160):
        import cv2

        from treeform.render import Renderer
        from treeform.structures import Camera

        s = min(1.0, height / camera.height)
        w, h = max(1, round(camera.width * s)), max(1, round(camera.height * s))
        self.camera = Camera(w, h, camera.fov_y, camera.position, camera.target, camera.up, camera.near, camera.far)
        small = cv2.resize(mask.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)
        self.mask = small >= 0.5
        self._renderer = Renderer(self.camera, samples=1)

    def error(self, mesh) -> tuple[float, np.ndarray]:
        """(eq. 3 error, rendered silhouette) of ``mesh``."""
        from treeform.metrics import reprojection_error

        sil = self._renderer.render(mesh).mask
        return float(reprojection_error(sil, self.mask)), sil

    def release(self) -> None:
        self._renderer.release()
