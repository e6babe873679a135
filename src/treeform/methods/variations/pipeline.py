"""Image-based tree variations (seed 000): library processing, variations, morphs, billboards.

* :func:`process_library` — every RGBA tree of a directory -> processed
  :class:`~treeform.methods.variations.exemplar.Exemplar` (§4.1–4.6), cached per file
  (npz keyed by the file's SHA-256 and the processing options);
* :func:`vary` — n new trees from random convex combinations of exemplars of the same
  growth form (§5.1–5.2, :mod:`.form`), or variations of a given tree T (§3), optionally
  given the crown and trunk colours of a photographed tree (§5.3, :mod:`.season`); PNGs,
  ``contact_sheet.png`` and ``config.json``;
* :func:`morph` — the morph between two trees, ``(1 - t) u_A + t u_B`` (§5.1, Fig. 7);
* :func:`billboard` — photo -> RGBA billboard by segmentation, trimap and alpha matting
  (§4.3, Fig. 4; in :mod:`.billboard`, re-exported here).

Every output is written atomically (temporary names, then renames); nothing is left
behind when a step fails.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from treeform import __version__
from treeform._shared.errors import InputError, TreeformError
from treeform._shared.rng import as_rng
from treeform._shared.timing import ProgressCallback, StageTimer
from treeform.io.images import read_rgba
from treeform.io.outputs import check_out_dir, check_out_file, write_staged
from treeform.methods.variations.billboard import BILLBOARD_STAGES, Billboard, billboard
from treeform.methods.variations.config import VariationsConfig
from treeform.report.preview import over_checkerboard
from treeform.methods.variations.exemplar import (
    IMAGE_SUFFIXES,
    Exemplar,
    file_hash,
    process_exemplar,
)
from treeform.methods.variations.season import SeasonReference, season_reference, season_transfer
from treeform.methods.variations.synthesis import Synthesis, synthesize

__all__ = ["Library", "Variations", "Morph", "Billboard", "process_library", "load_exemplar", "vary", "morph",
           "billboard", "contact_sheet", "default_cache_dir", "vary_stages", "LIBRARY_STAGES",
           "MORPH_STAGES", "BILLBOARD_STAGES"]

log = logging.getLogger(__name__)

LIBRARY_STAGES = ("library", "export")
MORPH_STAGES = ("library", "morph", "export")


def vary_stages(n: int) -> tuple:
    """Stage names :func:`vary` reports for ``n`` variations (for a progress bar's total)."""
    k = int(n) if 1 <= int(n) <= 10_000 else 0  # out of range: vary() says so before any work
    return ("library",) + tuple(f"variation {i + 1}/{k}" for i in range(k)) + ("export",)


def _config(config: VariationsConfig | None, options: dict) -> VariationsConfig:
    return VariationsConfig.from_dict({**(config.to_dict() if config else {}), **options})


# --------------------------------------------------------------------------- pictures


def contact_sheet(images, *, tile: int = 256, cols: int | None = None, gap: int = 4,
                  background=(255, 255, 255)) -> np.ndarray:
    """Tiles side by side in a grid; RGBA images are shown over a checkerboard.

    Parameters
    ----------
    images : sequence of ndarray, (H, W, 3) or (H, W, 4) uint8
    tile : int
        Each image is scaled to fit a ``tile`` x ``tile`` cell (aspect kept, centred).
    cols : int, optional
        Columns (default: about square).

    Returns
    -------
    ndarray, shape (rows * (tile + gap) + gap, cols * (tile + gap) + gap, 3), uint8
    """
    import cv2

    ims = list(images)
    if not ims:
        raise InputError("images: nothing to put on a contact sheet")
    cols = int(cols or int(np.ceil(np.sqrt(len(ims)))))
    rows = int(np.ceil(len(ims) / cols))
    out = np.empty((rows * (tile + gap) + gap, cols * (tile + gap) + gap, 3), np.uint8)
    out[:] = background
    for i, im in enumerate(ims):
        im = np.asarray(im)
        h, w = im.shape[:2]
        s = tile / max(h, w)
        size = (max(1, round(w * s)), max(1, round(h * s)))
        small = cv2.resize(im, size, interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR)
        if small.ndim == 3 and small.shape[2] == 4:
            small = over_checkerboard(small, cell=max(4, tile // 24))
        elif small.ndim == 2:
            small = np.repeat(small[..., None], 3, axis=2)
        r, c = divmod(i, cols)
        y = gap + r * (tile + gap) + (tile - size[1]) // 2
        x = gap + c * (tile + gap) + (tile - size[0]) // 2
        out[y:y + size[1], x:x + size[0]] = small[..., :3]
    return out


# --------------------------------------------------------------------------- output helpers


def _png(array):
    from treeform.io import write_png

    return lambda path: write_png(array, path)


# --------------------------------------------------------------------------- library


def default_cache_dir() -> Path:
    """Where processed exemplars are cached: ``$TREEFORM_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/treeform/exemplars``, else ``~/.cache/treeform/exemplars``."""
    env = os.environ.get("TREEFORM_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "treeform" / "exemplars"


def _check_cache(cache_dir) -> None:
    """A cache folder the caller named must be writable (only the default one is skipped quietly)."""
    if cache_dir is not None:
        check_out_dir(cache_dir, "--cache")


def _cache_key(digest: str, cfg: VariationsConfig) -> str:
    opts = json.dumps({"v": 1, **cfg.processing_key()}, sort_keys=True)
    return hashlib.sha256((digest + opts).encode()).hexdigest()


def load_exemplar(path, *, config: VariationsConfig | None = None, cache_dir=None, use_cache: bool = True,
                  **options) -> tuple[Exemplar, bool]:
    """Process one RGBA tree file, or load it from the cache.

    Parameters
    ----------
    path : path-like
        An RGBA image (PNG, WebP, TIFF).
    config : VariationsConfig, optional
    cache_dir : path-like, optional
        Default :func:`default_cache_dir`. A cache that cannot be written is skipped.
    use_cache : bool

    Returns
    -------
    exemplar : Exemplar
    from_cache : bool
    """
    cfg = _config(config, options)
    path = Path(path)
    rgba = None
    if not path.is_file():
        read_rgba(path)  # raises the right one-line InputError
    digest = file_hash(path)
    key = _cache_key(digest, cfg)
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    cached = cache / f"{key[:32]}.npz"
    if use_cache and cached.is_file():
        try:
            ex = Exemplar.load(cached)
            if ex.key == key:
                ex.name = path.name
                return ex, True
        except TreeformError:
            pass  # a stale or broken cache file: process again
    rgba = read_rgba(path)
    try:
        ex = process_exemplar(rgba, size=cfg.size, counts=cfg.counts, m=cfg.simplified_points, dilate=cfg.dilate,
                              margin=cfg.margin, name=path.name, key=key)
    except TreeformError as exc:
        raise type(exc)(f"{path}: {exc}") from None
    if use_cache:
        try:
            cache.mkdir(parents=True, exist_ok=True)
            ex.save(cached)
        except OSError as exc:
            log.warning("cannot write the exemplar cache %s (%s); continuing without it", cache, exc)
    return ex, False


@dataclass
class Library:
    """Processed exemplars of a tree library."""

    exemplars: list
    paths: list
    cache_dir: Path
    from_cache: int = 0
    sheet: Path | None = None

    @property
    def names(self) -> list[str]:
        return [Path(p).name for p in self.paths]

    def __len__(self) -> int:
        return len(self.exemplars)


def _library_files(library) -> list[Path]:
    if isinstance(library, (list, tuple)):
        files = [Path(p) for p in library]
    else:
        d = Path(library)
        if not d.exists():
            raise InputError(f"{d}: no such directory")
        if d.is_file():
            raise InputError(f"{d}: is a file; a library is a directory of RGBA tree images")
        files = sorted(p for p in d.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            raise InputError(f"{d}: no RGBA tree images ({', '.join(IMAGE_SUFFIXES)}) in the directory")
    return files


def process_library(library, *, cache_dir=None, sheet=None, config: VariationsConfig | None = None,
                    progress: ProgressCallback | None = None, use_cache: bool = True, **options) -> Library:
    """Process every RGBA tree of a library directory (seed 000 §4), with a cache.

    Parameters
    ----------
    library : path-like or sequence of path-like
        A directory of RGBA tree images (.png, .webp, .tif), or a list of files.
    cache_dir : path-like, optional
        Where processed exemplars are cached (default :func:`default_cache_dir`); each
        is an npz named by the SHA-256 of the image file and the processing options.
    sheet : path-like, optional
        Write a contact sheet of the processed exemplars (normalised image, Cr in
        cyan, Cs in red, crown baseline in orange, trunk in magenta, pins B / L / R).
    config : VariationsConfig, optional
    progress : callable, optional
        ``progress(stage, event, seconds)``; stages :data:`LIBRARY_STAGES`.
    use_cache : bool
    **options
        Overrides of config fields.

    Returns
    -------
    Library
    """
    cfg = _config(config, options)
    sheet_path = check_out_file(sheet, "--sheet") if sheet is not None else None
    _check_cache(cache_dir)
    timer = StageTimer(progress)
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    with timer.stage("library"):
        files = _library_files(library)
        exemplars, hits = [], 0
        for f in files:
            ex, hit = load_exemplar(f, config=cfg, cache_dir=cache, use_cache=use_cache)
            exemplars.append(ex)
            hits += hit
    lib = Library(exemplars, files, cache, hits)
    with timer.stage("export"):
        if sheet_path is not None:
            from treeform.io import write_png

            write_png(contact_sheet([exemplar_figure(e) for e in exemplars], tile=cfg.tile), sheet_path)
            lib.sheet = sheet_path
    return lib


def exemplar_figure(ex: Exemplar) -> np.ndarray:
    """The exemplar over a checkerboard with its contours drawn (seed 000 Fig. 5).

    Cr in cyan, Cs in red, the crown baseline in orange, the trunk tinted magenta and
    the pins B (black), L (blue), R (green).

    Returns
    -------
    ndarray, shape (S, S, 3), uint8
    """
    import cv2

    s = ex.size
    vis = over_checkerboard(ex.rgba, cell=max(4, s // 32)).copy()
    trunk = ex.labels == 2
    vis[trunk] = (0.45 * vis[trunk] + 0.55 * np.array([255, 0, 255])).astype(np.uint8)
    t = max(1, s // 300)
    if np.isfinite(ex.baseline):
        cv2.line(vis, (0, int(ex.baseline)), (s - 1, int(ex.baseline)), (255, 140, 0), t)
    cv2.polylines(vis, [np.rint(ex.resampled).astype(np.int32).reshape(-1, 1, 2)], True, (0, 200, 255), t)
    cv2.polylines(vis, [np.rint(ex.simplified).astype(np.int32).reshape(-1, 1, 2)], True, (230, 0, 0), t + 1)
    for p, c in zip(ex.pins, [(0, 0, 0), (0, 0, 255), (0, 160, 0)]):
        cv2.circle(vis, (int(round(p[0])), int(round(p[1]))), 4 * t, c, -1)
    return vis


# --------------------------------------------------------------------------- variations


@dataclass
class Variations:
    """What :func:`vary` made."""

    images: list
    records: list
    config: VariationsConfig
    sheet: np.ndarray | None = None
    files: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)


def _partners(lib: Library, first: int, k: int, rng, pairing: str, exclude=(), any_form: bool = True,
              warned=None) -> list[int]:
    """``k`` other exemplars for ``first``: random, or random among the 5 most similar contours
    (RMS distance of corresponding Cr points); near-duplicates of ``first`` are skipped.
    Unless ``any_form``, only exemplars of ``first``'s growth form (fewer than ``k`` if the
    library has fewer; other forms only when it has none, with a warning)."""
    others = [j for j in range(len(lib)) if j != first and j not in exclude]
    if k <= 0 or not others:
        return []
    if not any_form:
        form = lib.exemplars[first].form
        same = [j for j in others if lib.exemplars[j].form == form]
        if same:
            others = same
        elif warned is not None and first not in warned:
            warned.add(first)
            log.warning("%s: no other %s in the library; it is combined with other forms", lib.names[first], form)
    base = lib.exemplars[first].resampled
    d = np.array([np.sqrt(((lib.exemplars[j].resampled - base) ** 2).sum(1).mean()) for j in others])
    # near-duplicates (contours within 3 % of the image size) would give a copy of the tree
    distinct = d >= 0.03 * lib.exemplars[first].size
    if distinct.sum() >= k:
        others, d = [o for o, keep in zip(others, distinct) if keep], d[distinct]
    if pairing == "similar":
        order = [others[i] for i in np.argsort(d, kind="stable")]
        pool = order[:max(k, min(5, len(order)))]
    else:
        pool = others
    pick = rng.choice(len(pool), size=min(k, len(pool)), replace=False)
    return [pool[i] for i in sorted(pick)]


def _weights(k: int, lo: float, hi: float, rng) -> np.ndarray:
    if k == 1:
        return np.ones(1)
    if k == 2:
        w1 = rng.uniform(lo, hi)
        return np.array([w1, 1.0 - w1])
    return rng.dirichlet(np.full(k, 2.0))


def _season_reference(season, cfg: VariationsConfig) -> SeasonReference:
    """The crown and trunk colours of the tree in the ``season`` photo (or RGBA tree)."""
    if isinstance(season, SeasonReference):
        return season
    if isinstance(season, np.ndarray):
        image, name = season, "season"
    else:
        name = f"season: {season}"
        image = read_rgba(season, require_alpha=False)  # one-line errors for a bad file
        if not (image[..., 3] < 255).any():  # a photo: upright (EXIF) and reduced
            from treeform.io import read_photo

            image = read_photo(season, max_size=cfg.photo_max_size).image
    try:
        return season_reference(image, segmenter=cfg.segmenter, seed=cfg.seed, min_trunk=cfg.season_min_trunk)
    except TreeformError as exc:
        raise type(exc)(f"{name}: {exc}") from None


def vary(library, *, n: int = 20, out=None, from_tree=None, season=None, cache_dir=None,
         config: VariationsConfig | None = None, progress: ProgressCallback | None = None, **options) -> Variations:
    """New trees from a library of RGBA trees (seed 000 §3, §5).

    Each variation combines ``exemplars_per_variation`` exemplars: a random first one and
    partners of the same growth form (broadleaf, conifer or palm, from the silhouettes,
    :mod:`.form`; any form with ``any_form=True``) among the most similar contours
    (``pairing='similar'``), contour weights w1 ~ U(``weight_range``) (§7: [0.3, 0.7]),
    random colour weights (Dirichlet(``colour_concentration``), §5.2). With ``from_tree``
    T, T is always first and its weight is drawn from ``from_weight_range`` (higher
    weight on T's features, §3), for both contour and colour. With ``season`` every
    variation takes the colours of the tree in that photo, crown and trunk apart
    (§5.3, :func:`~.season.season_transfer`).

    Parameters
    ----------
    library : path-like, sequence of path-like, or Library
        Directory of RGBA tree images.
    n : int
        Number of variations (>= 1).
    out : path-like, optional
        Directory for ``variation_000.png`` ... , ``contact_sheet.png`` and ``config.json``
        (written only when every variation succeeded).
    from_tree : path-like, optional
        An RGBA tree T to make variations of.
    season : path-like, ndarray or SeasonReference, optional
        A photo of a tree whose colours the variations take (segmented first; only its
        tree counts), or an RGBA tree (its alpha is the mask).
    cache_dir : path-like, optional
        Exemplar cache (default :func:`default_cache_dir`).
    config : VariationsConfig, optional
    progress : callable, optional
        ``progress(stage, event, seconds)``; stages :func:`vary_stages`.
    **options
        Overrides of config fields, e.g. ``seed=3, simplified_points=40``.

    Returns
    -------
    Variations
        ``images`` (n arrays (S, S, 4) uint8), ``records`` (exemplar names and forms,
        contour and colour weights per variation), ``sheet``, ``files``.
    """
    cfg = _config(config, options)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= 10_000:
        raise InputError(f"n: expected an integer in [1, 10000], got {n!r}")
    out_dir = check_out_dir(out) if out is not None else None
    _check_cache(cache_dir)
    timer = StageTimer(progress)
    rng = as_rng(cfg.seed)
    with timer.stage("library"):
        ref = _season_reference(season, cfg) if season is not None else None
        lib = library if isinstance(library, Library) else process_library(library, cache_dir=cache_dir, config=cfg)
        t_index = None
        if from_tree is not None:
            t_ex, _ = load_exemplar(from_tree, config=cfg, cache_dir=cache_dir if cache_dir is not None
                                    else lib.cache_dir)
            same = [j for j, e in enumerate(lib.exemplars) if e.key == t_ex.key]
            if same:
                t_index = same[0]
            else:
                lib = Library(lib.exemplars + [t_ex], lib.paths + [Path(from_tree)], lib.cache_dir, lib.from_cache)
                t_index = len(lib) - 1
        if len(lib) < 2 and cfg.exemplars_per_variation > 1:
            raise InputError(f"library: {len(lib)} exemplar(s); at least 2 are needed to make variations")
    k = min(cfg.exemplars_per_variation, len(lib))
    images, records, warned = [], [], set()
    pick = dict(any_form=cfg.any_form, warned=warned)
    for i in range(n):
        with timer.stage(f"variation {i + 1}/{n}"):
            if t_index is None:
                first = int(rng.integers(len(lib)))
                chosen = [first] + _partners(lib, first, k - 1, rng, cfg.pairing, **pick)
                w = _weights(len(chosen), *cfg.weight_range, rng)
                b = rng.dirichlet(np.full(len(chosen), cfg.colour_concentration))
            else:
                chosen = [t_index] + _partners(lib, t_index, k - 1, rng, cfg.pairing, **pick)
                wt = rng.uniform(*cfg.from_weight_range)
                bt = rng.uniform(*cfg.from_weight_range)
                rest = rng.dirichlet(np.full(len(chosen) - 1, 2.0)) if len(chosen) > 1 else np.zeros(0)
                w = np.concatenate([[wt], (1 - wt) * rest]) if len(chosen) > 1 else np.ones(1)
                b = np.concatenate([[bt], (1 - bt) * rest]) if len(chosen) > 1 else np.ones(1)
            syn: Synthesis = synthesize([lib.exemplars[j] for j in chosen], w, colour_weights=b,
                                        m=cfg.simplified_points, mvc_step=cfg.mvc_step)
            img = syn.rgba if ref is None else season_transfer(syn.rgba, syn.labels, ref, space=cfg.season_space)
            images.append(img)
            records.append({"file": f"variation_{i:03d}.png", "exemplars": [lib.names[j] for j in chosen],
                            "forms": [lib.exemplars[j].form for j in chosen],
                            "weights": [round(float(x), 6) for x in syn.weights],
                            "colour_weights": [round(float(x), 6) for x in syn.colour_weights]})
    res = Variations(images, records, cfg)
    with timer.stage("export"):
        res.sheet = contact_sheet(images, tile=cfg.tile, cols=min(5, n))
        if out_dir is not None:
            files = {r["file"]: _png(im) for r, im in zip(records, images)}
            files["contact_sheet.png"] = _png(res.sheet)
            meta = {"treeform": __version__, "method": "variations", "library": [str(p) for p in lib.paths],
                    "from": str(from_tree) if from_tree is not None else None,
                    "season": str(season) if isinstance(season, (str, os.PathLike)) else None,
                    "season_trunk": ref.has_trunk if ref is not None else None,
                    "n": n, "config": cfg.to_dict(), "variations": records}
            files["config.json"] = lambda p: p.write_text(json.dumps(meta, indent=1, sort_keys=True))
            res.files = write_staged(out_dir, [lambda d, n=name, w=writer: w(d / n) for name, writer in files.items()])
    res.timings = {k_: round(v, 4) for k_, v in timer.timings.items()}
    return res


# --------------------------------------------------------------------------- morph


@dataclass
class Morph:
    """What :func:`morph` made: frames at ``ts`` and the strip of them."""

    frames: list
    ts: np.ndarray
    strip: np.ndarray
    contours: list
    files: dict = field(default_factory=dict)


def morph(a, b, *, steps: int = 7, out=None, cache_dir=None, config: VariationsConfig | None = None,
          progress: ProgressCallback | None = None, **options) -> Morph:
    """Morph between two RGBA trees (seed 000 §5.1–5.2, Figs. 6–7).

    Frame k has contour ``(1 - t) Cr_A + t Cr_B`` with ``t = k / (steps - 1)`` and the
    colours of both trees with the same weights; t = 0 and t = 1 reproduce A and B.

    Parameters
    ----------
    a, b : path-like or Exemplar
    steps : int
        Number of frames (>= 2).
    out : path-like, optional
        PNG file for the strip (frames side by side over a checkerboard).
    cache_dir : path-like, optional
    config : VariationsConfig, optional
    progress : callable, optional
        Stages :data:`MORPH_STAGES`.

    Returns
    -------
    Morph
    """
    cfg = _config(config, options)
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or not 2 <= steps <= 1000:
        raise InputError(f"steps: expected an integer in [2, 1000], got {steps!r}")
    out_path = check_out_file(out) if out is not None else None
    _check_cache(cache_dir)
    timer = StageTimer(progress)
    with timer.stage("library"):
        ex = [x if isinstance(x, Exemplar) else load_exemplar(x, config=cfg, cache_dir=cache_dir)[0] for x in (a, b)]
    frames, contours = [], []
    ts = np.linspace(0.0, 1.0, int(steps))
    with timer.stage("morph"):
        for t in ts:
            syn = synthesize(ex, [1.0 - t, t], m=cfg.simplified_points, mvc_step=cfg.mvc_step)
            frames.append(syn.rgba)
            contours.append(syn.contour)
        strip = contact_sheet(frames, tile=cfg.tile, cols=len(frames))
    res = Morph(frames, ts, strip, contours)
    with timer.stage("export"):
        if out_path is not None:
            from treeform.io import write_png

            write_png(strip, out_path)
            res.files = {"strip": out_path}
    return res
