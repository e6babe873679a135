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

__all__ = ["Proposal", "propose", "prior", "SilhouetteScorer", "best_so_far"]

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

    def to_dict(self) -> dict:
        return asdict(self)


ERROR_SCALE = 0.02
"""Likelihood p(I | M) = exp(-error / ERROR_SCALE) in eq. (4): 2 points more of eq. (3) error
cost as much as a factor e^-1 of the prior (n about 1.4 standard deviations from its mean), so
the prior breaks near-ties without overruling a clearly better fit."""


def score(error: float, n_branches: int, species: str) -> float:
    """Log of eq. (4)'s posterior up to a constant: ``log p(M) - error / ERROR_SCALE``.

    Examples
    --------
    >>> score(0.05, 6, "oak") > score(0.09, 6, "oak") and score(0.05, 6, "oak") > score(0.05, 9, "oak")
    True
    """
    return math.log(max(prior(n_branches, species), 1e-300)) - float(error) / ERROR_SCALE


def prior(n_branches: int, species: str) -> float:
    """p(M) of eq. (4): the species' Gaussian on the number of first-order branches (peak 1)."""
    mean, sd, _ = SPECIES_PRIORS[species]
    return math.exp(-0.5 * ((n_branches - mean) / sd) ** 2)


def propose(count: int, species: str, *, n_branches: int | None = None, seed: int = 0) -> list[Proposal]:
    """``count`` distinct proposals, the first the prior's most likely model.

    The first proposal is the "single model" of Fig. 13 (n at the prior's mean, the first cut
    draw, middle density and spread). The others draw n from the species' Gaussian (or keep
    ``n_branches``), one of a few cut draws per n, and a leaf density and distribution from
    :data:`~treeform.methods.synthesis.config.LEAF_DENSITIES` / ``LEAF_SPREADS``; repeats are
    skipped, so every proposal is a different model.

    Examples
    --------
    >>> ps = propose(5, "oak", seed=0)
    >>> len(ps), ps[0].n_branches, ps[0].density, len(set(ps))
    (5, 6, 9.0, 5)
    """
    mean, sd, _ = SPECIES_PRIORS[species]
    rng = np.random.default_rng([seed, 4004])
    first_n = n_branches if n_branches is not None else int(round(mean))
    mid_d, mid_s = LEAF_DENSITIES[len(LEAF_DENSITIES) // 2], LEAF_SPREADS[len(LEAF_SPREADS) // 2]
    out = [Proposal(first_n, 0, mid_d, mid_s, 0)]
    seen = {(first_n, 0, mid_d, mid_s)}
    tries = 0
    while len(out) < count and tries < 50 * count:
        tries += 1
        n = n_branches if n_branches is not None else int(np.clip(round(rng.normal(mean, sd)), 2, 14))
        key = (n, int(rng.integers(_SKELETON_DRAWS)), float(rng.choice(LEAF_DENSITIES)), float(rng.choice(LEAF_SPREADS)))
        if key in seen:
            continue
        seen.add(key)
        out.append(Proposal(*key, leaf_seed=int(rng.integers(2**31))))
    return out


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
