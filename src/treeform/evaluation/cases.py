"""Evaluation cases: a photo, and as much ground truth as exists for it.

``synthetic:N`` — N trees grown over the seven species and rendered photo-like from a random
camera by the dataset generator (:func:`treeform.dataset.synthetic.make_sample`): true mask,
mesh, skeleton, RBV and species. ``captures:N`` — N trees grown over the seven species and
photographed by :data:`CAPTURE_VIEWS` cameras walking around each at eye height in a 3D park
(:func:`treeform.dataset.capture.synthetic_capture`, :data:`CAPTURE_SIZE` px wide): the
multi-view method reconstructs from all the photos, a single-photo method from the first;
both are scored against the same truth (the first photo's mask, the true tree and its RBV seen
from that photo's camera). ``photos:DIR`` — the photos of a folder; a mask beside a
photo (``NAME_mask.png``, white = tree) is its ground truth, else it has none and the front
silhouette is scored against the method's own segmentation only (marked as such).
"""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError
from treeform.io.images import PHOTO_SUFFIXES

__all__ = ["CAPTURE_SIZE", "CAPTURE_VIEWS", "Case", "capture_case", "case_names", "load_case"]

CAPTURE_VIEWS = 24
"""Photos of a ``captures:N`` case (the multi-view method's acceptance capture has 24)."""
CAPTURE_SIZE = 480
"""Width in pixels of a ``captures:N`` case's photos (4:3)."""


@dataclass
class Case:
    """One evaluation case.

    Attributes
    ----------
    name : str
        ``synthetic-S-I`` (seed S, index I), ``capture-S-I`` or ``photo-STEM``.
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
    photos : Path or None
        The folder of all the photos (capture cases; ``image`` is its first photo).
    cameras : dict or None
        The true cameras of those photos, ``{name: {"K", "cam_to_world", "size"}}`` (OpenCV
        axes, the truth's frame: :meth:`treeform.sfm.SfmResult.cameras_json`'s format).
    workdir : Path or None
        A temporary folder the case owns (its capture); :meth:`close` removes it.
    gt_metrics : dict or None
        The true tree's :func:`treeform.metrics.tree_metrics`, filled by the first score that
        needs them (shared by the methods scored on the case).
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
    photos: Path | None = None
    cameras: dict | None = field(default=None, repr=False)
    workdir: Path | None = None
    gt_metrics: dict | None = field(default=None, repr=False)

    def close(self) -> None:
        """Remove the case's temporary files (a capture's photos); safe to call twice."""
        if self.workdir is not None:
            shutil.rmtree(self.workdir, ignore_errors=True)
            self.workdir = None


def case_names(cases: str, *, seed: int = 0) -> list[str]:
    """The case names of a ``--cases`` spec, in order.

    >>> case_names("synthetic:3", seed=5)
    ['synthetic-5-0', 'synthetic-5-1', 'synthetic-5-2']
    """
    kind, _, arg = str(cases).partition(":")
    if kind in ("synthetic", "captures"):
        try:
            n = int(arg)
        except ValueError:
            n = -1
        if n < 1:
            raise InputError(f"--cases {cases}: expected {kind}:N with N >= 1")
        return [f"{kind.rstrip('s')}-{int(seed)}-{i}" for i in range(n)]
    if kind == "photos":
        folder = Path(arg)
        if not folder.is_dir():
            raise InputError(f"--cases {cases}: {folder} is not a directory")
        files = sorted(p for p in folder.iterdir() if p.suffix.lower() in PHOTO_SUFFIXES
                       and not p.stem.endswith("_mask"))
        if not files:
            raise InputError(f"--cases {cases}: no photos in {folder}")
        return [f"photo:{p}" for p in files]
    raise InputError(f"--cases {cases}: expected synthetic:N, captures:N or photos:DIR")


def display_name(name: str) -> str:
    """Short, file-safe name of a case (``photo:/a/b/oak.jpg`` -> ``photo-oak.jpg``)."""
    if name.startswith("photo:"):
        base = Path(name[len("photo:"):]).name
        return "photo-" + "".join(c if c.isalnum() or c in "-_." else "_" for c in base)
    return name


def load_case(name: str, *, size: int = 256) -> Case:
    """Make or read the case ``name`` (from :func:`case_names`)."""
    for kind, make in (("synthetic", _synthetic), ("capture", _capture)):
        if name.startswith(kind + "-"):
            try:
                _, seed, index = name.split("-")
                seed, index = int(seed), int(index)
            except ValueError:
                raise InputError(f"case {name}: expected {kind}-SEED-INDEX") from None
            return make(seed, index, size)
    if name.startswith("photo:"):
        return _photo(Path(name[len("photo:"):]))
    raise InputError(f"case {name}: unknown kind")


def _synthetic(seed: int, index: int, size: int) -> Case:
    from treeform.dataset.synthetic import SampleOptions, make_sample

    s = make_sample(seed, index, SampleOptions(size=size))
    return Case(name=f"synthetic-{seed}-{index}", image=s.image, gt_mask=s.mask > 0, mask_source="ground truth",
                gt_mesh=s.mesh, gt_skeleton=s.skeleton, azimuth_deg=float(s.meta["camera"]["azimuth_deg"]),
                rbv=s.rbv, species=s.species)


def _capture(seed: int, index: int, size: int) -> Case:
    """A synthetic capture around one tree (species by index, as the synthetic cases cycle them).

    ``size`` (the single-photo cases' image size) is not used: the photos are
    :data:`CAPTURE_SIZE` wide, enough for structure from motion.
    """
    from treeform.dataset.capture import synthetic_capture
    from treeform.growth.species import SPECIES

    species = SPECIES[index % len(SPECIES)]
    tree_seed = int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1)[0])
    work = Path(tempfile.mkdtemp(prefix="treeform-capture-"))
    try:
        cap = synthetic_capture(work / "capture", views=CAPTURE_VIEWS, size=CAPTURE_SIZE, species=species,
                                seed=tree_seed)
        return capture_case(cap, f"capture-{seed}-{index}", workdir=work)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise


def capture_case(cap, name: str, *, workdir: Path | None = None) -> Case:
    """The case of a synthetic capture (:class:`treeform.dataset.capture.CaptureResult`) with a skeleton truth.

    ``image`` is its first photo, seen by the single-photo methods; ``photos`` all of them.
    ``workdir`` (removed by :meth:`Case.close`) is the folder the case owns, if any.
    """
    from PIL import Image

    from treeform.dataset.capture import _read_model
    from treeform.dataset.synthetic import canonical_rbv
    from treeform.io.images import read_photo
    from treeform.structures import TreeSkeleton

    if "skeleton" not in cap.truth:
        raise InputError(f"{cap.out}: a capture of a GLB model has no skeleton truth to score against")
    cameras = json.loads(Path(cap.truth["cameras"]).read_text())
    meta = json.loads(Path(cap.truth["meta"]).read_text())
    first = Path(cap.images[0])
    photo = read_photo(first)
    with Image.open(cap.truth["labels"][0]) as im:  # labels 0 background, 1 foliage, 2 wood
        gt = np.asarray(im) > 0
    skeleton = TreeSkeleton.load(cap.truth["skeleton"])
    c = np.asarray(cameras[first.name]["cam_to_world"], np.float64)[:3, 3] - skeleton.positions[0]
    azimuth = math.degrees(math.atan2(c[0], c[2]))  # the camera at (sin a, ., cos a) around the base
    return Case(name=name, image=photo.image, gt_mask=gt, mask_source="ground truth",
                gt_mesh=_read_model(Path(cap.truth["tree"])), gt_skeleton=skeleton, azimuth_deg=azimuth,
                rbv=canonical_rbv(skeleton, azimuth)[0], species=meta.get("species"), photos=Path(cap.out) / "images",
                cameras=cameras, workdir=workdir)


def _photo(path: Path) -> Case:
    from treeform.io.images import read_mask, read_photo

    ph = read_photo(path)
    mask_path = next((p for p in (path.with_name(f"{path.stem}_mask{e}") for e in (".png", ".jpg")) if p.exists()), None)
    gt = read_mask(mask_path, ph.shape) if mask_path is not None else None
    return Case(name=display_name(f"photo:{path}"), image=ph.image, gt_mask=None if gt is None else np.asarray(gt, bool),
                mask_source="mask file" if gt is not None else "none")
