"""The sample set shipped with treeform, so that every README example runs anywhere.

``treeform sample-data --out samples`` writes:

- ``photo.jpg``: *Celtis occidentalis* (common hackberry), public domain (see ATTRIBUTION.md);
- ``autumn.jpg``: the same photo with its crown turned orange by treeform's season
  recolouring (a reference for ``vary --season``);
- ``library/``: 14 RGBA trees, treeform's own seven species grown and rendered alone
  (``scripts/make_sample_library.py``; CC0), exemplars for ``vary``, ``morph`` and ``library``;
- ``group.jpg``: three of those trees standing on a lawn (:func:`group_photo`; CC0), the sample
  of ``reconstruct --all-trees``.

Nothing is downloaded: all of it is in the installed package.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

import numpy as np

SAMPLE_PHOTO = "Celtis_occidentalis_1.jpg"


def data_path(name: str) -> Path:
    """Path of a file shipped in ``treeform/data`` (e.g. :data:`SAMPLE_PHOTO`, ``"library"``)."""
    return Path(str(files("treeform") / "data" / name))


def library_files() -> list[Path]:
    """The shipped exemplar PNGs, sorted by name."""
    return sorted(data_path("library").glob("*.png"))


def autumn_photo(image: np.ndarray, *, season: str = "orange", seed: int = 0) -> np.ndarray:
    """``image`` (H, W, 3) uint8 with its main tree's foliage recoloured to ``season``.

    The foliage comes from the classical segmentation, narrowed to leaf-coloured pixels
    (hue 35°–170°, some saturation) so sky seen through the crown keeps its colour, as do
    the lawn, the trunk and everything else. ``season`` is one of
    :data:`treeform.dataset.scenes.SEASONS`.
    """
    import cv2

    from treeform.dataset.scenes import recolor_season
    from treeform.segment import segment

    seg = segment(image, method="classical", seed=seed)
    hsv = cv2.cvtColor(image, cv2.COLOR_RGB2HSV_FULL)
    hue = hsv[..., 0].astype(np.float32) * (360.0 / 256.0)
    leafy = (seg.labels == 1) & (hue >= 35) & (hue <= 170) & (hsv[..., 1] >= 40)
    return recolor_season(image, leafy, season, np.random.default_rng(seed))


def write_sample_data(out, *, progress=None) -> dict:
    """Write the sample set into ``out`` (created if needed); returns ``{name: path}``.

    Existing sample files are replaced; other files in ``out`` are left alone. Each file
    is written atomically.

    Raises
    ------
    OutputError
        ``out`` cannot be created or written.
    """
    import shutil

    from PIL import Image

    from treeform._shared.errors import OutputError
    from treeform._shared.timing import StageTimer
    from treeform.io._atomic import atomic_path
    from treeform.io.images import read_photo

    out = Path(out)
    timer = StageTimer(progress)
    try:
        (out / "library").mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"--out {out}: cannot create ({exc.strerror or exc})") from None
    written = {}
    with timer.stage("photo"):
        with atomic_path(out / "photo.jpg") as tmp:
            shutil.copyfile(data_path(SAMPLE_PHOTO), tmp)
        written["photo.jpg"] = out / "photo.jpg"
    with timer.stage("autumn"):
        img = autumn_photo(read_photo(data_path(SAMPLE_PHOTO)).image)
        with atomic_path(out / "autumn.jpg") as tmp:
            Image.fromarray(img).save(tmp, format="JPEG", quality=92)
        written["autumn.jpg"] = out / "autumn.jpg"
    with timer.stage("library"):
        for src in library_files():
            dst = out / "library" / src.name
            with atomic_path(dst) as tmp:
                shutil.copyfile(src, tmp)
            written[f"library/{src.name}"] = dst
    with timer.stage("group"):
        with atomic_path(out / "group.jpg") as tmp:
            Image.fromarray(group_photo()).save(tmp, format="JPEG", quality=92)
        written["group.jpg"] = out / "group.jpg"
    return written


SAMPLE_STAGES = ("photo", "autumn", "library", "group")

GROUP_TREES = (("apple_1.png", -4.5, 15.0, 6.5), ("oak_4.png", 1.0, 19.0, 7.5), ("maple_2.png", 5.5, 16.0, 6.0))
"""The trees of :func:`group_photo`: library file, metres right of the camera's axis, metres ahead, height."""


def group_photo() -> np.ndarray:
    """A photo of three trees of the library standing on a lawn, 15-19 m from a camera 1.6 m up.

    (720, 960, 3) uint8, the same every time: the sample of ``reconstruct --all-trees``
    (:func:`treeform.dataset.scenes.group_scene`, 40 degrees vertical field of view; the trees
    as :data:`GROUP_TREES` places them).
    """
    from treeform.dataset.scenes import group_scene, load_cutouts

    sprites = {s.name: s for s in load_cutouts(data_path("library"))}
    names, x, z, h = zip(*GROUP_TREES)
    return group_scene([sprites[n] for n in names], np.c_[x, z], h, np.random.default_rng(0))["image"]
