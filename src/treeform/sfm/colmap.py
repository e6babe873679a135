"""Structure from motion with COLMAP (pycolmap): photos -> :class:`SfmResult` (seed 002 §3).

The stages, each timed in ``meta["seconds"]`` and reported through ``progress(stage, event,
seconds)``:

``sfm.write``
    The upright, resized photos are written as PNG into a work folder, one sub-folder per
    camera group (same size and same focal prior: one COLMAP camera, ``SIMPLE_RADIAL``).
``sfm.extract``
    SIFT on the CPU; the focal priors from EXIF are set on the cameras
    (``has_prior_focal_length``).
``sfm.match``
    Exhaustive matching up to :data:`EXHAUSTIVE_MAX` photos; above, the pairs are chosen
    offline and without a vocabulary tree: neighbours in name order (with the loop around the
    tree closed) and the nearest photos by a bag of visual words built from the photos' own
    SIFT descriptors (:func:`retrieval_pairs`).
``sfm.map``
    Incremental mapping; the largest model is kept. Where it leaves photos out, a run with looser
    thresholds (:data:`RELAXED_MAPPER`) replaces it if it registers more photos and agrees with
    it on the photos both hold; where it holds every photo, more runs (other seeds, the looser
    thresholds) replace it if they hold every photo too and reproject better (:data:`MAPPER_RUNS`).
``sfm.convert``
    COLMAP's model -> :class:`SfmResult`, and the checks for a degenerate model.

Determinism: the photos are imported before the (threaded) SIFT extraction so their ids do not
depend on which thread finishes first; RANSAC of the two-view verification and the mapper are
seeded with ``seed``; the pairs and the retrieval vocabulary are deterministic; each mapper run
is on one thread (with more, COLMAP's per-thread random generators change the model from run to
run), up to ``num_threads`` runs at once, each seeded in its own thread. So the same photos give
the same model on the same machine: bitwise in every repeat we made (24 views at 1024 px in two
processes; the test capture a hundred times) but one, where 5 of 1682 points differed after a
test run under load, cause unknown. SIFT and matching use
``num_threads`` threads; each photo and each pair is computed alone, so there the thread count
changes only the timing.

Timing (24 rendered views at 1024 x 768, 4096 features, two cores): write 1 s, SIFT 11-12 s,
exhaustive matching of 276 pairs 28-30 s, mapping 4.6 s: about 46 s; ``matcher="retrieval"``
(141 pairs) 32 s with the same accuracy. 2026-11-28, on the capture of ``bench_multiview.py``:
SIFT 10 s, matching 17 s, the four mapper runs 18 s one after another, 9 s two at a time. Since
2026-11-29 photos of :data:`OCTAVE_ZERO_FROM` pixels or more are first registered at their own scale:
that capture's SfM takes 11 s (SIFT 3.6 s, matching 3.1 s, mapping 3.0 s).
"""

from __future__ import annotations

import logging
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError, SfmError, TreeformError
from treeform._shared.timing import ProgressCallback, StageTimer
from treeform.sfm.evaluate import pose_errors
from treeform.sfm.photos import MIN_PHOTOS, PhotoView
from treeform.sfm.result import SfmResult

__all__ = ["run_sfm", "import_pycolmap", "retrieval_pairs", "sequential_pairs", "check_geometry", "convergence_point",
           "MATCHERS", "EXHAUSTIVE_MAX", "STAGES"]

log = logging.getLogger(__name__)

MATCHERS = ("auto", "exhaustive", "sequential", "retrieval")
"""Values of ``run_sfm(matcher=...)``."""

EXHAUSTIVE_MAX = 25
"""``matcher="auto"`` matches every pair up to this many photos, above it uses ``"retrieval"``.

Exhaustive matching costs n(n-1)/2 pairs (~0.2 CPU-seconds each with 4096 features at 1024 px):
300 pairs at 25 photos keep SfM within about a minute on two cores; retrieval matches about 6n
pairs."""

OCTAVE_ZERO_FROM = 800
"""``run_sfm(first_octave=None)``: photos whose median long side is at least this many pixels are
registered first with SIFT at their own scale (``first_octave=0``), and again with the image doubled
(-1) only where that leaves a photo out; smaller photos go straight to -1. On the 24-view captures
of 1024 x 768 px (``bench_multiview.py``) the own scale holds every photo at a quarter of the time
(oak 44 -> 11 s, Cesium tree 35 -> 8 s) with poses as close to the truth (position median 0.18 ->
0.12 % of the ring, rotation 0.23 -> 0.14 degrees on the oak); on the oak's 10-photo subset it holds
3 of 10 (-1: all 10) and a 480-px capture fails, hence the size and the second try."""
STAGES = ("sfm.write", "sfm.extract", "sfm.match", "sfm.map", "sfm.convert")
"""Stage names reported through ``progress(stage, event, seconds)``, in order."""

SEQUENTIAL_OVERLAP = 10
"""``matcher="sequential"``: each photo is matched with this many next ones (plus 2^k steps)."""

RETRIEVAL_K = 8
"""``matcher="retrieval"``: each photo is matched with its this many most similar photos ..."""

RETRIEVAL_OVERLAP = 2
"""... and with this many next ones in name order (the loop closed)."""

RELAXED_MAPPER = {"abs_pose_min_num_inliers": 15, "abs_pose_min_inlier_ratio": 0.15, "init_min_num_inliers": 50}
"""The incremental mapper's thresholds for its second try (COLMAP's defaults: 30, 0.25 and 100).

Where the first model leaves photos out, the mapper runs again on the same matches with these
looser thresholds, and that model is kept only where it registers more photos and puts the
photos the first model holds where the first model does (:data:`AGREE_ROTATION_DEG`,
:data:`AGREE_POSITION`); where the first holds every photo, see :data:`MAPPER_RUNS`. Looser thresholds alone register more photos of a leafy tree, where
few features match from one view to the next (24 views of a grown apple tree at 1024 px: 12 ->
24 registered, median position error 0.32 -> 0.69 % of the scene; a willow at 480 px: 13 -> 24),
but on sparse captures (16 views) they build wrong models (median rotation errors of 2.7-6.2
degrees against 0.3-1.1 for the first model). On 14 synthetic captures the wrong models
disagreed with the first on its own photos by 2.3-9.4 degrees (median rotation) and 2.2-20 %
(farthest centre), the good ones by 0.2-1.2 degrees and 0.5-1.1 % (BENCHMARKS.md)."""

MAPPER_RUNS = 3
"""Where the mapper registers every photo, it runs again on the same matches with the seeds ``seed +
1``, ..., ``seed + MAPPER_RUNS - 1`` and once with :data:`RELAXED_MAPPER`; of the runs that register
every photo, the model with the lowest mean reprojection error is kept. One run can settle into a
wrong model of every photo: on 38 synthetic captures, single runs 15-34 % of the ring off (rotations
9-39 degrees) held every photo of four; the lowest reprojection error chose a right run (camera
position error 0.2-1.1 %) on each of the four, and on two others a slightly worse one than the first
run's (2.1 against 0.8 %, 3.9 against 3.1 %; BENCHMARKS.md, multi-view). Not where photos are left
out: on a capture whose runs register 3-8 of 24 photos, one run took 9 minutes."""

AGREE_ROTATION_DEG = 1.5
"""The second model agrees with the first when, after a similarity fit of the centres of the photos
both hold, their median rotation differs by at most this many degrees ..."""

AGREE_POSITION = 0.015
"""... and no centre is farther than this fraction of the first model's camera spread from the first
model's."""

MIN_BASELINE = 0.02
"""A model whose camera centres spread less than this fraction of the scene depth is rotation-only."""


def import_pycolmap():
    """Import pycolmap after the system zlib is loaded, and return the module.

    pycolmap 4.2's ``_core`` carries its own zlib symbols; when it is the first library to
    load ``libz.so.1``, later PNG writes of OpenCV and Pillow abort in ``deflateEnd`` (or
    hang). Loading zlib, OpenCV and Pillow first avoids it: import pycolmap through this
    function.

    Raises
    ------
    SfmError
        pycolmap is not installed.
    """
    import zlib  # noqa: F401  (loads libz.so.1 where zlib is a shared module)

    import cv2  # noqa: F401
    from PIL import Image  # noqa: F401

    try:
        import pycolmap
    except ImportError as exc:  # pragma: no cover - a declared dependency
        raise SfmError(f"structure from motion needs pycolmap ({exc}); install it: pip install pycolmap") from None
    return pycolmap


@contextmanager
def _quiet_colmap():
    """Silence COLMAP's glog lines on stderr (unless this module's logger shows DEBUG)."""
    pycolmap = import_pycolmap()
    lg = pycolmap.logging
    if log.isEnabledFor(logging.DEBUG):
        yield
        return
    old = lg.minloglevel
    lg.minloglevel = 3  # FATAL only: every failure becomes one SfmError line
    try:
        yield
    finally:
        lg.minloglevel = old


def _camera_groups(views: list[PhotoView], per_photo: bool) -> list[int]:
    """Group index per view: same size and same focal prior share a COLMAP camera."""
    keys, groups = {}, []
    for i, v in enumerate(views):
        key = i if per_photo else (v.size, None if v.focal_px is None else round(v.focal_px, 1))
        groups.append(keys.setdefault(key, len(keys)))
    return groups


def _write_images(views, groups, image_dir: Path) -> list[str]:
    import cv2

    names = []
    for i, (v, g) in enumerate(zip(views, groups)):
        rel = f"cam{g:03d}/{i:05d}.png"
        (image_dir / rel).parent.mkdir(parents=True, exist_ok=True)
        if not cv2.imwrite(str(image_dir / rel), np.ascontiguousarray(v.image[..., ::-1]),
                           [cv2.IMWRITE_PNG_COMPRESSION, 1]):
            raise SfmError(f"could not write the SfM work image {image_dir / rel}")
        names.append(rel)
    return names


def sequential_pairs(n: int, *, overlap: int = 3, quadratic: bool = True, loop: bool = True) -> list[tuple[int, int]]:
    """Pairs of photos close in name order (photos taken walking around the tree).

    Each photo is paired with the next ``overlap`` ones and, with ``quadratic``, with the
    ones 2^k further (k < 6); with ``loop`` the order wraps around (the walk ends where it
    began).

    Returns
    -------
    list of (i, j) with i < j, sorted

    Examples
    --------
    >>> sequential_pairs(5, overlap=1)
    [(0, 1), (0, 2), (0, 3), (0, 4), (1, 2), (1, 3), (1, 4), (2, 3), (2, 4), (3, 4)]
    """
    steps = set(range(1, overlap + 1)) | ({2 ** k for k in range(6)} if quadratic else set())
    pairs = set()
    for i in range(n):
        for s in steps:
            j = i + s
            if j >= n:
                if not loop:
                    continue
                j %= n
            if j != i:
                pairs.add((min(i, j), max(i, j)))
    return sorted(pairs)


def retrieval_pairs(descriptors: list[np.ndarray], *, k: int = 10, words: int = 256, seed: int = 0,
                    per_image: int = 1500) -> list[tuple[int, int]]:
    """The ``k`` most similar photos of each photo by a bag of visual words (no vocabulary file).

    A vocabulary of ``words`` SIFT words is clustered (k-means, seeded) from the photos' own
    descriptors; each photo becomes a tf-idf histogram and photos are paired with their ``k``
    nearest by cosine similarity.

    Parameters
    ----------
    descriptors : list of ndarray, each (N_i, 128)
        SIFT descriptors per photo (uint8 or float).
    k : int
    words : int
    seed : int
    per_image : int
        Descriptors per photo used (evenly spaced), bounding the cost.

    Returns
    -------
    list of (i, j) with i < j, sorted
    """
    n = len(descriptors)
    rng = np.random.default_rng(seed)
    sub = []
    for d in descriptors:
        d = np.asarray(d, np.float32).reshape(-1, 128)
        if len(d) > per_image:
            d = d[np.linspace(0, len(d) - 1, per_image).astype(int)]
        sub.append(d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-9))
    allv = np.concatenate(sub) if sub else np.zeros((0, 128), np.float32)
    if n < 2 or len(allv) == 0:
        return []
    train = allv[rng.choice(len(allv), min(len(allv), 200 * words), replace=False)] \
        if len(allv) > 200 * words else allv
    words = max(1, min(words, len(train)))
    cent = train[rng.choice(len(train), words, replace=False)].copy()
    for _ in range(8):  # Lloyd iterations (cosine on unit vectors)
        lab = np.argmax(train @ cent.T, axis=1)
        for w in range(words):
            m = lab == w
            if m.any():
                c = train[m].sum(0)
                cent[w] = c / max(np.linalg.norm(c), 1e-9)
    hist = np.zeros((n, words))
    for i, d in enumerate(sub):
        if len(d):
            hist[i] = np.bincount(np.argmax(d @ cent.T, axis=1), minlength=words)
    idf = np.log(n / np.maximum((hist > 0).sum(0), 1))
    h = hist * idf
    h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-12)
    sim = h @ h.T
    np.fill_diagonal(sim, -np.inf)
    pairs = set()
    for i in range(n):
        order = np.lexsort((np.arange(n), -sim[i]))  # most similar first, ties by index
        for j in order[:min(k, n - 1)]:
            pairs.add((min(i, int(j)), max(i, int(j))))
    return sorted(pairs)


def _extract(db_path, image_dir, names, max_features, first_octave, num_threads):
    pycolmap = import_pycolmap()

    ro = pycolmap.ImageReaderOptions()
    ro.camera_model = "SIMPLE_RADIAL"
    eo = pycolmap.FeatureExtractionOptions()
    eo.num_threads = num_threads
    eo.use_gpu = False
    eo.sift.max_num_features = int(max_features)
    eo.sift.first_octave = int(first_octave)
    # importing first fixes the image ids in the given order (the threaded extractor would
    # number the photos in the order its threads finish, and the mapper depends on the ids)
    pycolmap.Database.open(db_path).close()  # creates the database
    pycolmap.import_images(db_path, image_dir, camera_mode=pycolmap.CameraMode.PER_FOLDER, image_names=names,
                           options=ro)
    pycolmap.extract_features(db_path, image_dir, image_names=names, camera_mode=pycolmap.CameraMode.PER_FOLDER,
                              reader_options=ro, extraction_options=eo, device=pycolmap.Device.cpu)


def _set_focal_priors(db_path, views, groups, names) -> dict:
    """Put each group's EXIF focal prior on its COLMAP camera; returns {image_name: image_id}."""
    pycolmap = import_pycolmap()

    db = pycolmap.Database.open(db_path)
    try:
        images = {im.name: im for im in db.read_all_images()}
        cams = {c.camera_id: c for c in db.read_all_cameras()}
        ids = {}
        for i, name in enumerate(names):
            if name not in images:
                raise SfmError(f"COLMAP could not read {views[i].name}")
            im = images[name]
            ids[name] = im.image_id
            cam, f = cams[im.camera_id], views[i].focal_px
            if f is not None and not cam.has_prior_focal_length:
                w, h = views[i].size
                cam.params = [f, w / 2.0, h / 2.0, 0.0]
                cam.has_prior_focal_length = True
                db.update_camera(cam)
        return ids
    finally:
        db.close()


def _read_descriptors(db_path, image_ids) -> list[np.ndarray]:
    pycolmap = import_pycolmap()

    db = pycolmap.Database.open(db_path)
    try:
        return [np.asarray(db.read_descriptors(i).data) for i in image_ids]
    finally:
        db.close()


def _match(db_path, workdir: Path, matcher, names, image_ids, num_threads, seed, max_matches) -> dict:
    pycolmap = import_pycolmap()

    mo = pycolmap.FeatureMatchingOptions()
    mo.num_threads = num_threads
    mo.use_gpu = False
    mo.guided_matching = False
    mo.max_num_matches = int(max_matches)
    vo = pycolmap.TwoViewGeometryOptions()
    vo.ransac.random_seed = int(seed)
    n = len(names)
    if matcher == "exhaustive":
        pycolmap.match_exhaustive(db_path, matching_options=mo, verification_options=vo, device=pycolmap.Device.cpu)
        return {"pairs": n * (n - 1) // 2}
    if matcher == "sequential":
        pairs = set(sequential_pairs(n, overlap=SEQUENTIAL_OVERLAP))
    else:
        pairs = set(sequential_pairs(n, overlap=RETRIEVAL_OVERLAP, quadratic=False))
        pairs |= set(retrieval_pairs(_read_descriptors(db_path, [image_ids[m] for m in names]), k=RETRIEVAL_K,
                                     seed=seed))
    pairs = sorted(pairs)
    lst = workdir / "pairs.txt"
    lst.write_text("".join(f"{names[i]} {names[j]}\n" for i, j in pairs))
    po = pycolmap.ImportedPairingOptions()
    po.match_list_path = str(lst)
    pycolmap.match_image_pairs(db_path, matching_options=mo, pairing_options=po, verification_options=vo,
                               device=pycolmap.Device.cpu)
    return {"pairs": len(pairs)}


def _verified_pairs(db_path, min_inliers: int = 15) -> int:
    pycolmap = import_pycolmap()

    db = pycolmap.Database.open(db_path)
    try:
        _, inliers = db.read_two_view_geometry_num_inliers()
        return int(sum(1 for v in inliers if v >= min_inliers))
    finally:
        db.close()


def _map(db_path, image_dir, out_dir, seed, relaxed: bool = False):
    pycolmap = import_pycolmap()

    opts = pycolmap.IncrementalPipelineOptions()
    # one thread: with more, COLMAP's per-thread random generators make the model differ from
    # run to run (seen with 2 threads: 8 or 10 photos registered from the same database)
    opts.num_threads = 1
    opts.mapper.num_threads = 1
    opts.random_seed = int(seed)
    opts.mapper.random_seed = int(seed)
    opts.triangulation.random_seed = int(seed)
    opts.min_model_size = MIN_PHOTOS
    opts.multiple_models = True
    opts.max_num_models = 10
    opts.extract_colors = True
    opts.ba_refine_principal_point = False
    if relaxed:
        for k, v in RELAXED_MAPPER.items():
            setattr(opts.mapper, k, v)
    out_dir.mkdir(parents=True, exist_ok=True)
    return pycolmap.incremental_mapping(db_path, image_dir, out_dir, options=opts)


def _map_runs(db_path, image_dir, work: Path, jobs: list, num_threads: int) -> list:
    """Mapper runs, ``jobs`` = [(folder, seed, relaxed)], up to ``num_threads`` at once.

    Each run is one COLMAP thread seeded in its own Python thread (COLMAP's random generators
    are per thread; pycolmap lets go of the GIL while it maps), so the models are those of the
    runs made one after another: the same registered photos, points and poses (checked on the
    24-view 1024-px capture), in half the time on two cores.

    Runs at once each map from their own copy of the database (``<folder>/database.db``, copied
    before any starts): COLMAP opens its database for writing, and two runs opening one SQLite
    file at the same moment sometimes fail ("No registered database factory succeeded").
    """
    import shutil

    pycolmap = import_pycolmap()
    at_once = num_threads > 1 and len(jobs) > 1
    dbs = {}
    for folder, _, _ in jobs:
        dbs[folder] = db_path
        if at_once:
            (work / folder).mkdir(parents=True, exist_ok=True)
            dbs[folder] = shutil.copyfile(db_path, work / folder / "database.db")

    def one(job):
        folder, seed, relaxed = job
        pycolmap.set_random_seed(seed)
        return _map(dbs[folder], image_dir, work / folder, seed, relaxed=relaxed)

    if not at_once:
        return [one(job) for job in jobs]
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(min(num_threads, len(jobs))) as pool:
        return list(pool.map(one, jobs))


def _convert(rec, views, names_by_colmap: dict) -> SfmResult:
    """COLMAP reconstruction -> SfmResult (names sorted; K with the principal point folded in)."""
    reg = []
    for image_id in rec.reg_image_ids():
        im = rec.images[image_id]
        reg.append((views[names_by_colmap[im.name]].name, image_id))
    reg.sort()
    index = {image_id: c for c, (_, image_id) in enumerate(reg)}
    C = len(reg)
    K, c2w, sizes, radial = np.zeros((C, 3, 3)), np.zeros((C, 4, 4)), np.zeros((C, 2), np.int64), {}
    xy = {}
    for c, (name, image_id) in enumerate(reg):
        im = rec.images[image_id]
        cam = rec.cameras[im.camera_id]
        f, cx, cy, k1 = (float(v) for v in cam.params)
        K[c] = [[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]]
        w2c = np.eye(4)
        w2c[:3, :4] = im.cam_from_world().matrix()
        c2w[c] = np.linalg.inv(w2c)
        c2w[c, 3] = [0.0, 0.0, 0.0, 1.0]
        sizes[c] = (cam.width, cam.height)
        radial[name] = k1
        xy[image_id] = np.array([p.xy for p in im.points2D], np.float64).reshape(-1, 2)
    pids = sorted(rec.points3D.keys())
    pts = np.zeros((len(pids), 3))
    cols = np.zeros((len(pids), 3), np.uint8)
    errs = np.zeros(len(pids))
    tracks = []
    for n, pid in enumerate(pids):
        p = rec.points3D[pid]
        pts[n], cols[n], errs[n] = p.xyz, p.color, p.error
        els = sorted((index[e.image_id], e.point2D_idx, e.image_id) for e in p.track.elements)
        tr = np.array([(c, *xy[iid][idx]) for c, idx, iid in els], np.float64).reshape(-1, 3)
        tracks.append(tr)
    unregistered = sorted(set(v.name for v in views) - set(n for n, _ in reg))
    return SfmResult([n for n, _ in reg], K, c2w, sizes, pts, cols, errs, tracks, unregistered,
                     {"radial_k1": radial})


def convergence_point(result: SfmResult) -> tuple[np.ndarray, float]:
    """The point closest (least squares) to all optical axes, and the conditioning of that fit.

    Returns
    -------
    point : ndarray, shape (3,)
    conditioning : float
        Smallest / largest eigenvalue of the normal matrix, in [0, 1]; near 0 when the axes
        are (nearly) parallel and the point is undetermined.
    """
    A, b = np.zeros((3, 3)), np.zeros(3)
    for T in result.cam_to_world:
        d = T[:3, 2] / np.linalg.norm(T[:3, 2])
        M = np.eye(3) - np.outer(d, d)
        A += M
        b += M @ T[:3, 3]
    ev = np.linalg.eigvalsh(A)
    cond = float(ev[0] / ev[-1]) if ev[-1] > 0 else 0.0
    return np.linalg.lstsq(A, b, rcond=None)[0], cond


def check_geometry(result: SfmResult) -> dict:
    """Checks that a model is a usable capture around an object; returns notes for ``meta``.

    Raises
    ------
    SfmError
        Fewer than 3 registered photos; a rotation-only model (camera centres within
        :data:`MIN_BASELINE` of the scene depth: the photos were taken from one spot); or
        cameras that do not face a common object (optical axes parallel, or their meeting
        point behind or outside the view of most cameras).
    """
    C = result.n_cameras
    if C < MIN_PHOTOS:
        raise SfmError(f"only {C} of {C + len(result.unregistered)} photos could be registered; need at least "
                       f"{MIN_PHOTOS} (take more overlapping photos while walking around the tree)")
    centres = result.centers
    if len(result.points):
        ref = np.median(result.points, axis=0)
        depth = float(np.median(np.linalg.norm(result.points[None] - centres[:, None], axis=2)
                                if len(result.points) * C < 2_000_000 else np.linalg.norm(centres - ref, axis=1)))
    else:
        depth = float(np.median(np.linalg.norm(centres - centres.mean(0), axis=1))) or 1.0
    spread = float(np.sqrt(np.linalg.eigvalsh(np.cov(centres.T))[-1])) if C > 1 else 0.0
    baseline = spread / max(depth, 1e-12)
    if baseline < MIN_BASELINE:
        raise SfmError(f"degenerate model: the camera barely moved (spread {baseline:.1%} of the scene depth): "
                       "the photos were taken from one spot; walk around the tree between photos")
    X, cond = convergence_point(result)
    uvz = np.stack([result.project(X[None], i)[0] for i in range(C)])
    in_front = uvz[:, 2] > 0
    inside = in_front & (uvz[:, 0] >= 0) & (uvz[:, 0] <= result.sizes[:, 0]) & (uvz[:, 1] >= 0) \
        & (uvz[:, 1] <= result.sizes[:, 1])
    if cond < 1e-4 or in_front.mean() < 2 / 3 or inside.mean() < 0.5:
        raise SfmError("degenerate model: the cameras do not face a common object (their view axes do not meet "
                       f"in front of them: {int(inside.sum())} of {C} photos see the meeting point); "
                       "take the photos around the tree, facing it")
    return {"baseline_ratio": round(baseline, 4), "convergence_point": [round(float(v), 6) for v in X],
            "convergence_seen": round(float(inside.mean()), 3), "scene_depth": round(depth, 6)}


def run_sfm(views, *, workdir=None, max_features: int = 4096, first_octave: int | None = None, matcher: str = "auto",
            per_photo_camera: bool = False, num_threads: int = 2, seed: int = 0, check: bool = True,
            progress: ProgressCallback | None = None) -> SfmResult:
    """Register a photo collection with COLMAP: cameras and sparse 3D points (seed 002 §3).

    Parameters
    ----------
    views : list of PhotoView
        From :func:`treeform.sfm.photos.load_photos` (at least 3, unique names).
    workdir : path-like, optional
        Folder for COLMAP's images, database and models (kept); a temporary folder, removed
        afterwards, by default.
    max_features : int
        Most SIFT features per photo (before orientation duplicates).
    first_octave : {None, -1, 0}
        SIFT's first octave: -1 doubles the image first (more, smaller features: 2-3 x the
        points on 1024 px photos, at 3-4 x the time), 0 does not. None: 0 for photos of at least
        :data:`OCTAVE_ZERO_FROM` pixels, then -1 where that leaves a photo unregistered (the
        better model kept, ``meta["octave_tries"]``); -1 for smaller photos.
    matcher : {"auto", "exhaustive", "sequential", "retrieval"}
        Which pairs are matched: every pair; neighbours in name order
        (:data:`SEQUENTIAL_OVERLAP` on each side plus 2^k steps, the loop closed); or
        :data:`RETRIEVAL_OVERLAP` name neighbours plus the :data:`RETRIEVAL_K` most similar
        photos by a bag of words (:func:`retrieval_pairs`). ``"auto"``: exhaustive up to
        :data:`EXHAUSTIVE_MAX` photos, retrieval above.
    per_photo_camera : bool
        One COLMAP camera per photo (zoom changes between photos) instead of one per group
        of equal size and focal prior.
    num_threads : int
        CPU threads of SIFT extraction and matching (the mapper runs on one, see the module
        notes on determinism).
    seed : int
        Seeds RANSAC, the mapper and the retrieval vocabulary.
    check : bool
        Raise :class:`SfmError` on a degenerate model (see :func:`check_geometry`).
    progress : callable, optional
        ``progress(stage, event, seconds)`` over :data:`STAGES`.

    Returns
    -------
    SfmResult
        The largest model, in COLMAP's world (an arbitrary similarity; see
        :mod:`treeform.sfm.align`), of the mapper's run chosen as :data:`RELAXED_MAPPER` and
        :data:`MAPPER_RUNS` say (``meta["mapper_runs"]``: each run's registered photos and mean
        reprojection error, ``meta["mapper_run_kept"]`` the index of the one kept; ``meta["mapper"]``: the looser run's agreement where photos were left
        out). ``meta`` holds ``n_views``, ``n_registered``,
        ``n_models``, ``model_sizes``, ``n_points``, ``mean_reprojection_error``, ``seconds``
        per stage, ``focal_source`` per photo, ``matcher``, ``pairs``, ``verified_pairs``,
        ``radial_k1`` per photo (SIMPLE_RADIAL distortion, not in ``K``) and the geometry
        checks.

    Raises
    ------
    InputError
        Bad arguments (fewer than 3 views, duplicate names, unknown matcher ...).
    SfmError
        No model ("could not register the photos: ..."), fewer than 3 registered photos, or
        a degenerate model.
    """
    import_pycolmap()  # a clear error where pycolmap is missing, before any work
    views = list(views)
    if not all(isinstance(v, PhotoView) for v in views):
        raise InputError("views: expected a list of PhotoView (from treeform.sfm.load_photos)")
    if len(views) < MIN_PHOTOS:
        raise InputError(f"views: need at least {MIN_PHOTOS} photos of the tree, found {len(views)}")
    if len({v.name for v in views}) != len(views):
        raise InputError("views: photo names must be unique")
    if matcher not in MATCHERS:
        raise InputError(f"matcher: expected one of {', '.join(MATCHERS)}, got {matcher!r}")
    if isinstance(max_features, bool) or not isinstance(max_features, (int, np.integer)) or max_features < 64:
        raise InputError(f"max_features: expected an integer >= 64, got {max_features!r}")
    if first_octave is not None and (isinstance(first_octave, bool) or first_octave not in (-1, 0)):
        raise InputError(f"first_octave: expected None, -1 or 0, got {first_octave!r}")
    num_threads = max(1, int(num_threads))
    n = len(views)
    kw = dict(max_features=max_features, matcher=matcher, per_photo_camera=per_photo_camera,
              num_threads=num_threads, seed=seed, check=check, progress=progress)
    if first_octave is not None:
        return _run_once(views, workdir, first_octave, **kw)
    if np.median([max(v.image.shape[:2]) for v in views]) < OCTAVE_ZERO_FROM:
        result = _run_once(views, workdir, -1, **kw)
        result.meta["octave_tries"] = [[-1, result.n_cameras]]
        return result
    try:
        first = _run_once(views, workdir, 0, **kw)
    except SfmError:
        first = None
    tries = [[0, 0 if first is None else first.n_cameras]]
    if first is not None and first.n_cameras == n:
        first.meta["octave_tries"] = tries
        return first
    # a photo left out at the photos' own scale: again with the images doubled (more, smaller features)
    try:
        second = _run_once(views, None if workdir is None else Path(workdir) / "doubled", -1, **kw)
    except SfmError:
        if first is None:
            raise
        second = None
    tries.append([-1, 0 if second is None else second.n_cameras])
    result = second if _better(second, first) else first
    result.meta["octave_tries"] = tries
    return result


def _run_once(views, workdir, first_octave, *, max_features, matcher, per_photo_camera, num_threads, seed, check,
              progress) -> SfmResult:
    """One COLMAP registration of ``views`` (checked by :func:`run_sfm`) with SIFT from ``first_octave``."""
    pycolmap = import_pycolmap()
    n = len(views)
    used = "exhaustive" if (matcher == "auto" and n <= EXHAUSTIVE_MAX) else ("retrieval" if matcher == "auto"
                                                                             else matcher)
    timer = StageTimer(progress)
    tmp = None
    if workdir is None:
        tmp = tempfile.mkdtemp(prefix="treeform-sfm-")
        work = Path(tmp)
    else:
        work = Path(workdir)
        if work.exists() and any(work.iterdir()):
            raise InputError(f"workdir: {work} exists and is not empty")
        work.mkdir(parents=True, exist_ok=True)
    db_path, image_dir = str(work / "database.db"), work / "images"
    cseed = int(seed) % (2**31 - 1)  # COLMAP's seeds are 32-bit signed
    try:
        with _quiet_colmap():
            pycolmap.set_random_seed(cseed)
            with timer.stage("sfm.write"):
                groups = _camera_groups(views, per_photo_camera)
                names = _write_images(views, groups, image_dir)
            with timer.stage("sfm.extract"):
                _extract(db_path, image_dir, names, max_features, first_octave, num_threads)
                image_ids = _set_focal_priors(db_path, views, groups, names)
            with timer.stage("sfm.match"):
                match_info = _match(db_path, work, used, names, image_ids, num_threads, cseed, 16384)
                verified = _verified_pairs(db_path)
            by_name = {m: i for i, m in enumerate(names)}
            with timer.stage("sfm.map"):
                # the first run and the looser mapper's (the second opinion where photos are left out,
                # the last of the extra runs where none is) at once
                recs, recs_relaxed = _map_runs(db_path, image_dir, work, [("sparse", cseed, False),
                                                                          ("sparse_relaxed", cseed, True)],
                                               num_threads) if verified else ({}, {})
                sizes, result = _largest(recs, views, by_name)
                runs, second, chosen = [_run_note(result)], {}, 0
                if verified and (result is None or result.n_cameras < n):
                    # photos left out: the looser mapper, kept where it agrees (RELAXED_MAPPER)
                    sizes2, result2 = _largest(recs_relaxed, views, by_name)
                    second = _second_opinion(result, result2, n)
                    if second["kept"]:
                        recs, sizes, result = recs_relaxed, sizes2, result2
                elif verified:
                    # every photo registered, rightly or into a wrong model: more runs (other seeds, and
                    # the looser mapper), and of those holding every photo the one that reprojects best
                    # (MAPPER_RUNS)
                    more = _map_runs(db_path, image_dir, work, [(f"sparse{j}", (cseed + j) % (2**31 - 1), False)
                                                                for j in range(1, MAPPER_RUNS)], num_threads)
                    for j, recs_j in enumerate(more + [recs_relaxed], start=1):
                        sizes_j, result_j = _largest(recs_j, views, by_name)
                        runs.append(_run_note(result_j))
                        if result_j is not None and result_j.n_cameras == n and _better(result_j, result):
                            recs, sizes, result, chosen = recs_j, sizes_j, result_j, j
            with timer.stage("sfm.convert"):
                if result is None:
                    raise SfmError(f"could not register the photos: no model could be built ({verified} of "
                                   f"{match_info['pairs']} photo pairs share enough matching features; the photos "
                                   "must overlap, show a textured scene and be taken from different spots)")
                notes = check_geometry(result) if check else {}
    except TreeformError:
        raise
    except (RuntimeError, ValueError, OSError) as exc:  # COLMAP's own failures: one line, no traceback
        stage = list(timer.timings)[-1] if timer.timings else STAGES[0]  # the failing stage ends last
        raise SfmError(f"COLMAP failed ({stage.split('.')[1]}): {' '.join(str(exc).split())[:200]}") from exc
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    result.meta.update({
        "n_views": n, "n_registered": result.n_cameras, "n_unregistered": len(result.unregistered),
        "n_models": len(recs), "model_sizes": [s[0] for s in sizes], "n_points": int(len(result.points)),
        "mean_reprojection_error": round(_mean_error(result), 4) if len(result.errors) else None,
        "mean_track_length": round(float(np.mean([len(t) for t in result.tracks])), 3) if result.tracks else 0.0,
        "seconds": {**{k: round(v, 3) for k, v in timer.timings.items()},
                    "total": round(sum(timer.timings.values()), 3)},
        "focal_source": {v.name: v.focal_source for v in views},
        "n_cameras_colmap": int(max(groups) + 1), "matcher": used, "pairs": match_info["pairs"],
        "verified_pairs": verified, "max_features": int(max_features), "first_octave": int(first_octave),
        "seed": int(seed), "colmap": f"pycolmap {pycolmap.__version__}", "mapper": second or {"kept": False},
        "mapper_runs": runs, "mapper_run_kept": chosen,
        **notes,
    })
    return result


def _mean_error(result: SfmResult) -> float:
    """Mean reprojection error of a model's points (inf without points)."""
    return float(result.errors.mean()) if len(result.errors) else np.inf


def _run_note(result: SfmResult | None) -> list:
    """``[registered photos, mean reprojection error]`` of one mapper run (for ``meta["mapper_runs"]``)."""
    if result is None:
        return [0, None]
    return [result.n_cameras, round(_mean_error(result), 4) if len(result.errors) else None]


def _better(a: SfmResult | None, b: SfmResult | None) -> bool:
    """Whether model ``a`` beats ``b``: more registered photos, then a lower mean reprojection error."""
    if a is None:
        return False
    if b is None:
        return True
    if a.n_cameras != b.n_cameras:
        return a.n_cameras > b.n_cameras
    return _mean_error(a) < _mean_error(b)


def _largest(recs: dict, views, by_name: dict):
    """``(model sizes, SfmResult of the largest model)``; ``([], None)`` without a model."""
    if not recs:
        return [], None
    sizes = sorted(((r.num_reg_images(), r.num_points3D(), -k) for k, r in recs.items()), reverse=True)
    return sizes, _convert(recs[-sizes[0][2]], views, by_name)


def _second_opinion(first: SfmResult | None, second: SfmResult | None, n: int) -> dict:
    """Whether the relaxed mapper's model replaces the first one (:data:`RELAXED_MAPPER`), and why.

    Kept when it registers more photos and agrees with the first model on the photos both
    hold (:data:`AGREE_ROTATION_DEG`, :data:`AGREE_POSITION`); without a first model, when it
    registers at least half of the ``n`` photos and passes :func:`check_geometry`.
    """
    out = {"kept": False, "registered": 0 if second is None else second.n_cameras}
    if second is None or second.n_cameras <= (0 if first is None else first.n_cameras):
        return out
    if first is None or first.n_cameras < MIN_PHOTOS:
        if second.n_cameras < max(MIN_PHOTOS, n / 2):
            return out
        try:
            check_geometry(second)
        except SfmError:
            return out
        out["kept"] = True
        return out
    pe = pose_errors(second, first.cameras_json())
    if pe["registered"] < MIN_PHOTOS:
        return out
    out.update({"common": pe["registered"], "rotation_median_deg": round(pe["rotation_median_deg"], 3),
                "position_max_rel": round(pe["position_max_rel"], 4)})
    out["kept"] = bool(pe["rotation_median_deg"] <= AGREE_ROTATION_DEG and pe["position_max_rel"] <= AGREE_POSITION)
    return out
