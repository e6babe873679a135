"""Evaluation cases: a photo, and as much ground truth as exists for it.

``synthetic:N`` — N trees grown over the seven species and rendered photo-like from a random
camera by the dataset generator (:func:`treeform.dataset.synthetic.make_sample`): true mask,
mesh, skeleton, RBV and species. ``photos:DIR`` — the photos of a folder; a mask beside a
photo (``NAME_mask.png``, white = tree) is its ground truth, else it has none and the front
silhouette is scored against the method's own segmentation only (marked as such).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError

__all__ = ["Case", "case_names", "load_case"]

_PHOTO_EXT = (".jpg", ".jpeg", ".png", ".webp", ".tif", ".tiff", ".bmp")


@dataclass
class Case:
    """One evaluation case.

    Attributes
    ----------
    name : str
        ``synthetic-S-I`` (seed S, index I) or ``photo-STEM``.
    image : ndarray, shape (H, W, 3), uint8
    gt_mask : ndarray, shape (H, W), bool, or None
        True tree pixels.
    mask_source : str
        ``"ground truth"``, ``"mask file"`` or ``"none"``.
    gt_mesh, gt_skeleton : Mesh, TreeSkeleton, or None
        The true tree (synthetic cases).
    azimuth_deg : float
        The camera's azimuth around the tree (synthetic): turning the tree by minus this puts
        the camera on +Z, the frame every method reconstructs in.
    rbv : list of ndarray or None
        True normalised RBV levels 1–5 in that frame.
    species : str or None
    """

    name: str
    image: np.ndarray
    gt_mask: np.ndarray | None = None
    mask_source: str = "none"
    gt_mesh: object = field(default=None, repr=False)
    gt_skeleton: object = field(default=None, repr=False)
    gt_foliage: object = field(default=None, repr=False)
    azimuth_deg: float = 0.0
    rbv: list | None = field(default=None, repr=False)
    species: str | None = None


def case_names(cases: str, *, seed: int = 0) -> list[str]:
    """The case names of a ``--cases`` spec, in order.

    >>> case_names("synthetic:3", seed=5)
    ['synthetic-5-0', 'synthetic-5-1', 'synthetic-5-2']
    """
    kind, _, arg = str(cases).partition(":")
    if kind == "synthetic":
        try:
            n = int(arg)
        except ValueError:
            n = -1
        if n < 1:
            raise InputError(f"--cases {cases}: expected synthetic:N with N >= 1")
        return [f"synthetic-{int(seed)}-{i}" for i in range(n)]
    if kind == "photos":
        folder = Path(arg)
        if not folder.is_dir():
            raise InputError(f"--cases {cases}: {folder} is not a directory")
        files = sorted(p for p in folder.iterdir() if p.suffix.lower() in _PHOTO_EXT
                       and not p.stem.endswith("_mask"))
        if not files:
            raise InputError(f"--cases {cases}: no photos in {folder}")
        return [f"photo:{p}" for p in files]
    raise InputError(f"--cases {cases}: expected synthetic:N or photos:DIR")


def display_name(name: str) -> str:
    """Short, file-safe name of a case (``photo:/a/b/oak.jpg`` -> ``photo-oak.jpg``)."""
    if name.startswith("photo:"):
        base = Path(name[len("photo:"):]).name
        return "photo-" + "".join(c if c.isalnum() or c in "-_." else "_" for c in base)
    return name


def load_case(name: str, *, size: int = 256) -> Case:
    """Make or read the case ``name`` (from :func:`case_names`)."""
    if name.startswith("synthetic-"):
        try:
            _, seed, index = name.split("-")
            seed, index = int(seed), int(index)
        except ValueError:
            raise InputError(f"case {name}: expected synthetic-SEED-INDEX") from None
        return _synthetic(seed, index, size)
    if name.startswith("photo:"):
        return _photo(Path(name[len("photo:"):]))
    raise InputError(f"case {name}: unknown kind")


def _synthetic(seed: int, index: int, size: int) -> Case:
    from treeform.dataset.synthetic import SampleOptions, make_sample

    s = make_sample(seed, index, SampleOptions(size=size))
    return Case(name=f"synthetic-{seed}-{index}", image=s.image, gt_mask=s.mask > 0, mask_source="ground truth",
                gt_mesh=s.mesh, gt_skeleton=s.skeleton, azimuth_deg=float(s.meta["camera"]["azimuth_deg"]),
                rbv=s.rbv, species=s.species)


def _photo(path: Path) -> Case:
    from treeform.io.images import read_mask, read_photo

    ph = read_photo(path)
    mask_path = next((p for p in (path.with_name(f"{path.stem}_mask{e}") for e in (".png", ".jpg")) if p.exists()), None)
    gt = read_mask(mask_path, ph.shape) if mask_path is not None else None
    return Case(name=display_name(f"photo:{path}"), image=ph.image, gt_mask=None if gt is None else np.asarray(gt, bool),
                mask_source="mask file" if gt is not None else "none")
