"""Billboard cloud of a tree picture (seed 000 §6, Figs. 9–11): ``treeform cloud``.

:func:`cloud` runs the stages of :mod:`treeform.geometry.billboard_cloud` on one RGBA tree
picture (or a photo, made into one by :func:`~treeform.methods.variations.pipeline.billboard`):

1. **load** — the picture is normalised (§4.1) and split into crown and trunk (§4.3);
2. **superpixels** — SLIC of the crown;
3. **edges** — straight superpixel edges replaced by crown-silhouette curves;
4. **placement** — depths from the crown envelope's biharmonic height field
   (:func:`treeform.crown.inflate_envelope`, the project's one bilaplacian solver), front,
   rear and interior layers, the trunk;
5. **mesh** — one texture atlas, one MASK material, one quad per billboard;
6. **render** — the front view against the picture (PSNR, SSIM, silhouette IoU) and the
   turntable strip (front, 30°, 60°, 90°);
7. **export** — ``cloud.glb``, the ``cloud.json`` sidecar (the compact description of §6:
   source picture, crown/trunk segmentation, superpixel contours, billboard positions) and
   the strip, all or nothing;
8. **report** (only when asked) — a folder with ``report.html``: the input, the picture's
   alpha and crown/trunk split, the strip, the metrics, the seconds per stage and the cloud
   in the 3D viewer (:func:`write_cloud_report`, through
   :func:`treeform.report.write_run_report`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from treeform import __version__
from treeform._shared.errors import InputError, NoTreeFoundError
from treeform._shared.timing import ProgressCallback, StageTimer
from treeform.geometry.billboard_cloud import (
    CloudFrame,
    Placement,
    Regions,
    build_atlas,
    cloud_mesh,
    luminance,
    place_billboards,
    replace_straight_edges,
    superpixels,
)
from treeform.io.outputs import check_out_dir, check_out_file
from treeform.methods.variations.config import CloudConfig
from treeform.io import read_rgba
from treeform.methods.variations.exemplar import CROWN, TRUNK, file_hash, normalize_rgba, split_crown_trunk

__all__ = ["Cloud", "cloud", "front_quality", "turntable", "cloud_sidecar", "write_cloud_report", "CLOUD_STAGES"]

CLOUD_STAGES = ("load", "superpixels", "edges", "placement", "mesh", "render", "export")

SIDECAR_FORMAT = "treeform.billboard_cloud"
_MIN_CROWN = 64


@dataclass
class Cloud:
    """What :func:`cloud` made.

    Attributes
    ----------
    mesh : Mesh
        One part, one quad per billboard, MASK material with the atlas.
    picture : ndarray, shape (S, S, 4), uint8
        The normalised RGBA picture the cloud reproduces from the front.
    labels : ndarray, shape (S, S), uint8
        0 background, 1 crown, 2 trunk.
    superpixels : ndarray, shape (S, S), int32
        SLIC labels of the crown (0 elsewhere).
    regions : Regions
        Superpixels after straight-edge replacement.
    boxes : ndarray, shape (n, 4), int64
        Crop boxes: the regions, then the trunk (if any).
    placement : Placement
    atlas : ndarray, shape (Ha, Wa, 4), uint8
    rects : ndarray, shape (n, 4), int64
        Atlas rectangle of each crop.
    frame : CloudFrame
        Pixels -> metres and the reference camera.
    sidecar : dict
        The JSON sidecar.
    metrics : dict
        Billboard counts, atlas size, replaced edges, timings and, when rendered, ``psnr``,
        ``ssim`` and ``iou`` of the front view against the picture over the tree's pixels.
    strip : ndarray, shape (h, w, 3), uint8, or None
        Picture and views side by side.
    """

    mesh: object
    picture: np.ndarray
    labels: np.ndarray
    superpixels: np.ndarray
    regions: Regions
    boxes: np.ndarray
    placement: Placement
    atlas: np.ndarray
    rects: np.ndarray
    frame: CloudFrame
    sidecar: dict
    metrics: dict
    strip: np.ndarray | None = None
    files: dict = field(default_factory=dict)


def _load(image, cfg: CloudConfig) -> tuple[np.ndarray, dict]:
    """RGBA tree picture and a description of its source; photos go through the billboard path."""
    from treeform.methods.variations.pipeline import billboard

    if isinstance(image, np.ndarray):
        if image.ndim == 3 and image.shape[2] == 4 and image.dtype == np.uint8:
            return image, {"kind": "rgba", "file": None}
        if image.ndim == 3 and image.shape[2] == 3 and image.dtype == np.uint8:
            return billboard(image, seed=cfg.seed, segmenter=cfg.segmenter).rgba, {"kind": "photo", "file": None}
        raise InputError(f"image: expected an (H, W, 4) or (H, W, 3) uint8 array, got {image.shape} {image.dtype}")
    path = Path(image)
    rgba = read_rgba(path, require_alpha=False)
    source = {"file": path.name, "sha256": file_hash(path)}
    if (rgba[..., 3] < 128).any():
        return rgba, {**source, "kind": "rgba"}
    # no transparent pixel: a photo -> segmentation, trimap and alpha matting (§4.3)
    return billboard(path, seed=cfg.seed, segmenter=cfg.segmenter).rgba, {**source, "kind": "photo"}


def cloud(image, *, out=None, views=None, report=None, evaluate: bool | None = None,
          config: CloudConfig | None = None, progress: ProgressCallback | None = None, **options) -> Cloud:
    """Billboard cloud of a tree picture (seed 000 §6).

    Parameters
    ----------
    image : path-like or ndarray
        An RGBA tree picture (PNG, WebP, TIFF with transparency; used as it is) or a photo
        (no transparent pixel: made into an RGBA billboard first, §4.3), or such an array
        ((H, W, 4) or (H, W, 3) uint8).
    out : path-like, optional
        The ``.glb`` to write; the JSON sidecar goes beside it with the suffix ``.json``.
    views : path-like, optional
        A PNG of the picture and the views at ``config.views`` degrees (turntable strip).
    report : path-like, optional
        A folder for ``report.html`` (:func:`write_cloud_report`), written after the other
        outputs, whole or not at all; ``treeform cloud --report`` uses ``<out stem>_report``.
    evaluate : bool, optional
        Render the front view and measure it against the picture (default: when ``views``
        or ``report`` is given).
    config : CloudConfig, optional
    progress : callable, optional
        ``progress(stage, event, seconds)``; stages :data:`CLOUD_STAGES`, then ``report``
        when ``report`` is given.
    **options
        Overrides of config fields, e.g. ``segments=128, seed=3``.

    Returns
    -------
    Cloud

    Raises
    ------
    InputError
        Unreadable image, bad option, bad output name (``out`` must end in ``.glb``,
        ``views`` in ``.png``, ``report`` not a file).
    NoTreeFoundError
        The picture has (almost) no crown pixels.
    OutputError
        An output cannot be written (then none is).
    """
    cfg = CloudConfig.from_dict({**(config.to_dict() if config else {}), **options})
    glb_path = check_out_file(out, "-o", suffix=".glb") if out is not None else None
    strip_path = check_out_file(views, "--views") if views is not None else None
    report_dir = check_out_dir(report, "--report") if report is not None else None
    evaluate = (strip_path is not None or report_dir is not None) if evaluate is None else bool(evaluate)
    timer = StageTimer(progress)
    with timer.stage("load"):
        rgba, source = _load(image, cfg)
        picture = normalize_rgba(rgba, size=cfg.size)
        labels = split_crown_trunk(picture)
        crown = labels == CROWN
        if crown.sum() < _MIN_CROWN:
            raise NoTreeFoundError(f"the tree has almost no crown ({int(crown.sum())} px at {cfg.size}²): "
                                   "nothing to make a billboard cloud of")
    with timer.stage("superpixels"):
        sp = superpixels(picture[..., :3], crown, n_segments=cfg.segments, compactness=cfg.compactness,
                         max_side=cfg.slic_side)
    with timer.stage("edges"):
        tree = labels > 0
        regions = replace_straight_edges(sp, crown, within=tree, overlap=cfg.overlap,
                                         straightness=cfg.straightness, min_edge=cfg.min_edge,
                                         endpoint_tolerance=cfg.endpoint_tolerance, max_bulge=cfg.max_bulge,
                                         seed=cfg.seed)
    with timer.stage("placement"):
        from treeform.crown import inflate_envelope

        boxes, masks, trunk = regions.boxes, list(regions.masks), None
        if (labels == TRUNK).any():
            box, mask = _trunk_sprite(labels == TRUNK, tree, cfg.overlap)
            boxes, trunk = np.vstack([boxes, box]), len(masks)
            masks.append(mask)
        height = inflate_envelope(crown, k=None, depth_ratio=cfg.depth_ratio).front_z
        lum = luminance(picture, boxes, masks)
        placement = place_billboards(boxes, masks, lum, height, tree, crown=crown, trunk=trunk,
                                     push=cfg.push, interior=cfg.interior, darken=cfg.darken, yaw=cfg.yaw,
                                     max_leak=cfg.max_leak, seed=cfg.seed)
    with timer.stage("mesh"):
        atlas, rects = build_atlas(picture, boxes, masks)
        frame = CloudFrame.for_tree(tree, tree_height=cfg.tree_height, fov_y=cfg.fov_y)
        mesh = cloud_mesh(placement, boxes, rects, atlas, frame)
    metrics = {"billboards": len(placement), **placement.counts(), "superpixels": len(regions),
               "straight_edges": regions.straight, "replaced_edges": len(regions.curves),
               "atlas": [int(atlas.shape[1]), int(atlas.shape[0])], "triangles": mesh.n_triangles}
    strip = None
    with timer.stage("render"):
        if evaluate:
            metrics.update(front_quality(mesh, frame, picture))
        if strip_path is not None:
            strip = turntable(mesh, frame, picture, angles=cfg.views, size=cfg.view_size)
    sidecar = cloud_sidecar(source, picture, labels, regions, boxes, rects, placement, frame, cfg,
                            trunk=trunk)
    res = Cloud(mesh, picture, labels, sp, regions, boxes, placement, atlas, rects, frame, sidecar, metrics, strip)
    with timer.stage("export"):
        res.files = _write(res, glb_path, strip_path)
    res.metrics["timings"] = {k: round(v, 4) for k, v in timer.timings.items()}
    if report_dir is not None:
        with timer.stage("report"):
            res.files["report"] = write_cloud_report(res, report_dir, glb=glb_path, image=image)
    return res


def _trunk_sprite(trunk, tree, overlap: int) -> tuple[tuple, np.ndarray]:
    """Box ``(x0, y0, w, h)`` and mask of the trunk billboard: its pixels grown by ``overlap`` within the tree."""
    import cv2

    if overlap:
        trunk = cv2.dilate(trunk.astype(np.uint8), np.ones((3, 3), np.uint8), iterations=overlap).astype(bool) & tree
    ys, xs = np.nonzero(trunk)
    x0, y0, x1, y1 = xs.min(), ys.min(), xs.max() + 1, ys.max() + 1
    return (x0, y0, x1 - x0, y1 - y0), trunk[y0:y1, x0:x1]


def _write(res: Cloud, glb_path: Path | None, strip_path: Path | None) -> dict:
    """Sidecar, strip and GLB, all or nothing (the GLB renamed last)."""
    import json

    from treeform.io import write_glb, write_png
    from treeform.io._atomic import atomic_paths

    jobs = []  # (name, final path, writer of a temporary path)
    if glb_path is not None:
        jobs.append(("sidecar", glb_path.with_suffix(".json"),
                     lambda p: p.write_text(json.dumps(res.sidecar, separators=(",", ":")))))
    if strip_path is not None:
        jobs.append(("views", strip_path, lambda p: write_png(res.strip, p)))
    if glb_path is not None:
        jobs.append(("glb", glb_path, lambda p: write_glb(res.mesh, p)))
    if not jobs:
        return {}
    with atomic_paths([path for _, path, _ in jobs]) as temps:
        for (_, _, writer), tmp in zip(jobs, temps):
            writer(tmp)
    return {name: path for name, path, _ in jobs}


# --------------------------------------------------------------------------- report


def write_cloud_report(res: Cloud, folder, *, glb=None, image=None, title: str | None = None) -> Path:
    """``folder/report.html`` for a billboard cloud, whole or not at all.

    The page (:func:`treeform.report.write_run_report`) shows the input, the normalised
    picture's alpha beside its crown / trunk split, the turntable strip when one was made,
    ``res.metrics`` with their stage timings and, when ``glb`` is given, the cloud in the 3D
    viewer (its bytes copied into the folder as ``NAME.glb.js``, so the page opens offline).
    Everything is written into a temporary folder beside ``folder`` and then moved in.

    Parameters
    ----------
    res : Cloud
    folder : path-like
        Made if missing; files of an earlier report there are replaced.
    glb : path-like, optional
        The cloud's GLB, as written.
    image : path-like or ndarray, optional
        The input given to :func:`cloud`, shown first.
    title : str, optional
        Default: ``treeform cloud: <input file name>``.

    Returns
    -------
    Path
        The page.

    Raises
    ------
    OutputError
        The folder cannot be written (then nothing of the report is left).
    """
    import os
    import shutil
    import tempfile

    from treeform._shared.errors import OutputError
    from treeform.io._atomic import _UMASK
    from treeform.report import compose_strip, over_checkerboard, segmentation_overlay, write_run_report
    from treeform.structures import Segmentation

    folder = Path(folder)
    name = res.sidecar["source"].get("file") or "picture"
    title = title or f"treeform cloud: {name}"
    photo = res.sidecar["source"].get("kind") == "photo"
    pictures = []
    if image is not None:
        shown = np.asarray(image) if isinstance(image, np.ndarray) else read_rgba(Path(image), require_alpha=False)
        pictures.append((f"input: {name} ({'photo' if photo else 'RGBA picture'})", _input_tile(shown)))
    board = over_checkerboard(res.picture)
    pictures.append((("billboard made of the photo (alpha matting)" if photo else "the picture") +
                     ": alpha over a checkerboard | crown (green) and trunk (red)",
                     compose_strip([board, segmentation_overlay(board, Segmentation(res.labels))],
                                   labels=["alpha", "crown / trunk"], height=512)))
    if res.strip is not None:
        angles = ["front" if float(a) == 0 else f"{float(a):g}°" for a in res.sidecar["config"]["views"]]
        pictures.append(("views: " + " | ".join(["picture", *angles]), res.strip))
    try:
        stage = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".tmp", dir=folder.parent))
    except OSError as exc:
        raise OutputError(f"--report {folder}: cannot write ({exc.strerror or exc})") from None
    try:
        os.chmod(stage, 0o777 & ~_UMASK)
        write_run_report(stage, title=title, pictures=pictures, metrics=res.metrics, glb=glb)
        if not folder.exists():
            os.replace(stage, folder)
        else:  # an earlier report: its files replaced one by one
            for f in sorted(p for p in stage.rglob("*") if p.is_file()):
                dest = folder / f.relative_to(stage)
                dest.parent.mkdir(parents=True, exist_ok=True)
                os.replace(f, dest)
    except OSError as exc:
        raise OutputError(f"--report {folder}: write failed ({exc.strerror or exc})") from None
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    return folder / "report.html"


def _input_tile(img, side: int = 1024) -> np.ndarray:
    """The input as an RGB picture at most ``side`` pixels wide and high; transparency over a checkerboard."""
    import cv2

    from treeform.report import over_checkerboard

    img = np.asarray(img, np.uint8)
    if img.ndim == 3 and img.shape[2] == 4:
        img = img[..., :3] if (img[..., 3] == 255).all() else over_checkerboard(img)
    scale = side / max(img.shape[:2])
    if scale < 1:
        img = cv2.resize(img, (max(1, round(img.shape[1] * scale)), max(1, round(img.shape[0] * scale))),
                         interpolation=cv2.INTER_AREA)
    return img


# --------------------------------------------------------------------------- renders

_UNLIT = {"key": (0.0, 0.0, 0.0), "sky": (1.0, 1.0, 1.0), "ground": (1.0, 1.0, 1.0)}


def front_quality(mesh, frame: CloudFrame, picture) -> dict:
    """Render the cloud from the reference camera (unlit) and compare it with the picture.

    Returns
    -------
    dict
        ``psnr`` (dB) and ``ssim`` of the colours (both images over black) over the
        picture's tree pixels (alpha >= 0.5), ``iou`` of the rendered silhouette with them.
    """
    from treeform.metrics import iou, psnr, ssim
    from treeform.render import Lighting, Renderer

    picture = np.asarray(picture)
    res = Renderer(frame.camera(), samples=1, lighting=Lighting(**_UNLIT)).render(mesh)
    tree = picture[..., 3] >= 128
    # both over black, so that SSIM windows at the silhouette compare like with like
    rgb = np.where(res.mask[..., None], res.color[..., :3], 0)
    ref = np.where(tree[..., None], picture[..., :3], 0)
    return {"psnr": psnr(rgb, ref, tree), "ssim": ssim(rgb, ref, tree), "iou": iou(res.mask, tree)}


def turntable(mesh, frame: CloudFrame, picture, *, angles=(0.0, 30.0, 60.0, 90.0), size: int = 384) -> np.ndarray:
    """The picture and unlit views of the cloud orbiting the tree, side by side (seed 000 Fig. 11).

    Views are rendered by the reference camera (4x MSAA, white background) turned by each
    angle about the vertical axis through the picture's centre; each tile is labelled.

    Returns
    -------
    ndarray, shape (size + 8, n * (size + 4) + 4, 3), uint8
        ``n = len(angles) + 1`` tiles.
    """
    import cv2

    from treeform.methods.variations.pipeline import contact_sheet
    from treeform.render import Lighting, Renderer, to_uint8_rgb

    picture = np.asarray(picture)
    w = size if frame.width >= frame.height else max(1, round(size * frame.width / frame.height))
    h = size if frame.height >= frame.width else max(1, round(size * frame.height / frame.width))
    cam = frame.camera(w, h)
    tiles = [to_uint8_rgb(picture)]
    names = ["picture"]
    for a in angles:
        res = Renderer(cam.orbit(yaw_deg=float(a)), samples=4, lighting=Lighting(**_UNLIT)).render(mesh)
        tiles.append(to_uint8_rgb(res.color))
        names.append("front" if float(a) == 0 else f"{float(a):g} deg")
    sheet = contact_sheet(tiles, tile=size, cols=len(tiles))
    for i, name in enumerate(names):
        x, y = 4 + i * (size + 4) + 6, 4 + 18
        cv2.putText(sheet, name, (x, y), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (60, 60, 60), 1, cv2.LINE_AA)
    return sheet


# --------------------------------------------------------------------------- sidecar


def _runs(labels: np.ndarray) -> list[int]:
    """Row-major run-length encoding ``[value, length, value, length, ...]``."""
    flat = labels.ravel()
    starts = np.concatenate([[0], np.flatnonzero(np.diff(flat)) + 1])
    lengths = np.diff(np.append(starts, flat.size))
    return np.stack([flat[starts], lengths], 1).ravel().tolist()


def cloud_sidecar(source: dict, picture, labels, regions: Regions, boxes, rects, placement: Placement,
                  frame: CloudFrame, cfg: CloudConfig, *, trunk: int | None) -> dict:
    """The compact description of a billboard cloud (seed 000 §6, end).

    §6: the cloud "can be stored using the tree RGBA picture, the segmentation into crown
    and trunk, and the contour coordinates of each superpixel". Keys:

    * ``source`` — the input file's name and SHA-256 and whether it was an RGBA picture or
      a photo (made into one by ``treeform billboard`` with ``config.seed``); ``picture``
      — the normalised picture's size (§4.1, ``normalize_rgba(rgba, size=config.size)``);
    * ``segmentation`` — its labels (0 background, 1 crown, 2 trunk), run-length encoded
      row by row as ``[value, count, ...]``;
    * ``sprites`` — per crop: its box ``[x0, y0, w, h]`` in the picture, its atlas rectangle
      ``[u0, v0, w, h]``, its kind (``region`` or ``trunk``) and, for regions, the outer
      contours after edge replacement as flat ``[x0, y0, x1, y1, ...]`` pixel lists
      (filled, then kept on the crown, they give the crop's alpha exactly);
    * ``billboards`` — rows of ``columns``: crop index, layer (0 front, 1 rear, 2 interior,
      3 trunk), image position and depth in pixels, yaw (degrees), shade, and the world
      position of the centre (metres, Y up; :meth:`CloudFrame.to_world`);
    * ``frame`` — metres per pixel, the image position of the tree's base (world origin),
      the reference camera's field of view and distance; ``config`` — every option.
    """
    sprites = []
    for i, (box, rect) in enumerate(zip(np.asarray(boxes), np.asarray(rects))):
        s = {"box": [int(v) for v in box], "atlas": [int(v) for v in rect]}
        if i == trunk:
            s["kind"] = "trunk"
        else:
            s["kind"] = "region"
            s["contours"] = [c.ravel().tolist() for c in regions.contours[i]]
        sprites.append(s)
    world = frame.to_world(placement.x, placement.y, placement.z)
    rows = [[int(s), int(k), round(float(x), 2), round(float(y), 2), round(float(z), 2),
             round(float(np.degrees(a)), 2), round(float(sh), 4), *(round(float(c), 4) for c in p)]
            for s, k, x, y, z, a, sh, p in zip(placement.sprite, placement.layer, placement.x, placement.y,
                                                placement.z, placement.yaw, placement.shade, world)]
    return {
        "format": SIDECAR_FORMAT, "version": 1, "treeform": __version__,
        "source": source,
        "picture": {"width": int(picture.shape[1]), "height": int(picture.shape[0])},
        "segmentation": {"labels": {"0": "background", "1": "crown", "2": "trunk"}, "runs": _runs(labels)},
        "sprites": sprites,
        "billboards": {"columns": ["sprite", "layer", "x_px", "y_px", "z_px", "yaw_deg", "shade", "x", "y", "z"],
                       "rows": rows},
        "frame": {"metres_per_pixel": frame.metres_per_pixel, "origin_px": list(frame.origin),
                  "fov_y": frame.fov_y, "distance": round(frame.distance, 6)},
        "config": cfg.to_dict(),
    }
