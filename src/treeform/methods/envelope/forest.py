"""``treeform forest``: thousands of reconstructed trees with the level-of-detail switch (seed 001 §5.1).

N instances of one or more impostor sets (``treeform impostor``) are scattered over a ground
plane (blue noise, random scale and turn) and a camera flies over them. In every frame, after
culling to the view frustum, trees whose crown is nearer than the switch distance ``d`` are
drawn as **clipped billboard clouds** (16 to 144 leaflet billboards by screen size,
:class:`~treeform.render.cloud.CloudPass`) over their trunk and main limbs (``wood.glb``,
instanced), and the others as **relief-mapped radial distance maps**
(:class:`~treeform.render.impostor.ReliefPass`), but for crowns narrower than ``card_px``
pixels on screen, drawn as six-view **impostor cards** baked from the relief renderer. Each
representation of a species is one instanced draw call: one vertex buffer per species,
per-instance attributes (position, scale, turn, billboard count), no per-tree draw calls.

With ``baseline`` the same frames are drawn again with every visible tree as its full mesh
(``tree.glb``, instanced too), so the speed-up is measured side by side on the same machine.

Outputs (all or nothing): ``frames/frame_KKK.png`` (and ``frames/baseline_KKK.png``),
``contact_sheet.png``, ``timing.json`` (``ms_per_frame`` median over frames, each drawn after one
untimed frame that compiles the shaders and uploads the textures, per-frame
milliseconds by representation, trees per millisecond, visible / near / far trees, memory
per species, ``baseline_ms_per_frame`` and ``speedup`` with ``baseline``), ``instances.npy``
((N, 7): x, y, z, scale, yaw, 0, species index), ``config.json``; with ``glb``
``forest.glb`` (the forest for game engines: impostor cards, GPU-instanced); with ``html``
``forest.html`` (+ ``forest_data.js``, ``assets/``: the forest in a browser, three.js).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from treeform._shared.checks import check_int, check_positive
from treeform._shared.errors import InputError
from treeform._shared.timing import ProgressCallback, StageTimer

__all__ = ["FOREST_STAGES", "ForestConfig", "ForestResult", "Species", "fly_through", "load_species",
           "render_forest", "scatter_trees", "select_lod"]

FOREST_STAGES = ("load", "scatter", "cards", "frames", "baseline", "export")
_SKY = (0.72, 0.82, 0.93, 1.0)
_GROUND_RGB = (0.33, 0.38, 0.22)


@dataclass
class ForestConfig:
    """Every knob of :func:`render_forest`."""

    trees: int = 1000
    """Tree instances scattered over the area."""
    area: tuple = (400.0, 400.0)
    """Width (x) and depth (z) of the ground in metres, centred on the origin."""
    switch_distance: float = 200.0
    """The LoD switch d (seed 001 §5.1: d >= 150 m looks right, about 200 m is fastest):
    billboard clouds nearer, relief impostors beyond."""
    frames: int = 4
    """Frames of the fly-through."""
    size: tuple = (1920, 1080)
    """Frame width and height in pixels."""
    fov_y: float = 45.0
    """Vertical field of view in degrees."""
    scale: tuple = (0.8, 1.25)
    """Range of the instances' random scale."""
    relief_steps: int = 32
    """Linear-search samples of the relief impostor (then ``relief_refine`` bisections)."""
    relief_refine: int = 5
    full_billboards_px: float = 400.0
    """A crown this many pixels wide on screen (or more) gets 144 billboards; smaller ones fewer,
    by projected area, down to 16."""
    card_px: float = 32.0
    """Far trees whose crown is narrower than this many pixels on screen are drawn as their
    six-view impostor cards (:func:`~treeform.methods.envelope.engine.impostor_cards`: 12
    alpha-tested triangles, baked once per species by the relief renderer, the light in the
    texture) instead of the relief march; 0 keeps the relief for every far tree. A crown a few
    pixels wide shows no parallax the march could add, and its march costs per pixel: at 32 px
    a 50,000-tree frame took 0.8x the time (H100 and llvmpipe alike) and 0.3 % of its pixels
    changed by more than 16 / 255 (BENCHMARKS.md)."""
    baseline: bool = False
    """Also draw every frame with full meshes and record ``baseline_ms_per_frame``."""
    html: bool = False
    """Also write ``forest.html``: the forest in a browser, drawn by three.js with the renderer's
    own shaders (:mod:`~treeform.methods.envelope.web`), from the first frame's camera."""
    glb: bool = False
    """Also write ``forest.glb``: the ground and each species' impostor cards, GPU-instanced at its
    trees (``EXT_mesh_gpu_instancing``, :func:`~treeform.methods.envelope.engine.forest_glb`)."""
    seed: int = 0

    def validate(self) -> "ForestConfig":
        from treeform._shared.rng import as_rng

        self.trees = check_int(self.trees, "trees", 1, 2_000_000)
        self.area = _pair(self.area, "area", float)
        self.size = _pair(self.size, "size", int)
        if min(self.size) < 16 or max(self.size) > 8192:
            raise InputError(f"size: expected 16 to 8192 pixels a side, got {self.size[0]}x{self.size[1]}")
        self.switch_distance = check_positive(self.switch_distance, "switch_distance", allow_zero=True)
        self.frames = check_int(self.frames, "frames", 1, 1000)
        if not 1.0 <= float(self.fov_y) <= 120.0:
            raise InputError(f"fov_y: expected 1 to 120 degrees, got {self.fov_y}")
        lo, hi = _pair(self.scale, "scale", float)
        if lo > hi:
            raise InputError(f"scale: expected min <= max, got {lo}, {hi}")
        self.scale = (lo, hi)
        self.relief_steps = check_int(self.relief_steps, "relief_steps", 4, 1024)
        self.relief_refine = check_int(self.relief_refine, "relief_refine", 0, 32)
        self.full_billboards_px = check_positive(self.full_billboards_px, "full_billboards_px")
        self.card_px = check_positive(self.card_px, "card_px", allow_zero=True)
        as_rng(self.seed)
        return self


def _pair(value, name: str, kind) -> tuple:
    if isinstance(value, str):
        value = value.lower().replace("×", "x").split("x")
    try:
        a, b = (kind(float(v)) for v in value)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected two numbers like 400x300, got {value!r}") from None
    if not (a > 0 and b > 0) or not (math.isfinite(a) and math.isfinite(b)):
        raise InputError(f"{name}: expected two positive numbers, got {a}x{b}")
    return (a, b)


@dataclass
class Species:
    """One tree's representations, in its own frame (Y up, base at the origin)."""

    name: str
    impostor: object  # Impostor (read_impostor)
    mesh: object = None  # full Mesh (tree.glb), for the baseline
    source: Path | None = None

    @property
    def crown_center(self) -> np.ndarray:
        return np.asarray(self.impostor.rdm.center, np.float64)

    @property
    def crown_radius(self) -> float:
        """Radius of the sphere around the crown centre that holds the whole tree."""
        return float(np.max(self.impostor.rdm.radii))

    def memory_bytes(self, *, card_size: int = 0) -> dict:
        """GPU memory of the species' representations (uncompressed textures, with mip levels);
        ``card_size``: the edge of one view of its impostor cards, 0 when the forest draws none."""
        imp = self.impostor
        leaf = imp.leaflets.rgba.shape[0] * imp.leaflets.rgba.shape[1] * 4
        wood = sum(p.n_vertices * 48 + p.n_triangles * 12 for p in imp.wood.parts)
        wood_tex = sum(p.material.texture.size for p in imp.wood.parts if p.material.texture is not None)
        out = {"rdm": int(imp.rdm.radii.size * 4), "color_cubemap": int(imp.color.size),
               "opacity": int(imp.opacity.sigma.size * 2 + imp.opacity.wood.nbytes) if imp.opacity is not None else 0,
               "leaflet_textures": int(3 * leaf * 4 / 3), "billboard_points": int(imp.cloud_points.nbytes),
               "wood": int(wood + wood_tex * 4 / 3)}
        if card_size:
            out["impostor_cards"] = int(6 * card_size * card_size * 4 * 4 / 3 + 24 * 32)
        out["total"] = int(sum(out.values()))
        return out


def load_species(species_dir, *, need_mesh: bool = False) -> list[Species]:
    """The impostor sets under ``species_dir``: its sub-folders' ``impostor/`` (or itself).

    Raises
    ------
    InputError
        No impostor found, or (``need_mesh``) a tree without its ``tree.glb``.
    """
    from treeform.io.gltf import read_glb_mesh
    from treeform.methods.envelope.impostor import read_impostor

    root = Path(species_dir)
    if not root.is_dir():
        raise InputError(f"{root}: not a folder")
    dirs = [root] if _has_impostor(root) else sorted(d for d in root.iterdir() if d.is_dir() and _has_impostor(d))
    if not dirs:
        raise InputError(f"{root}: no impostor here (run `treeform impostor TREE_DIR` on each tree first)")
    out = []
    for d in dirs:
        imp = read_impostor(d)
        tree_dir = d.parent if (d / "impostor.json").is_file() else d  # d: an impostor/ folder, or its tree's
        glb = tree_dir / "tree.glb"
        mesh = None
        if need_mesh:
            if not glb.is_file():
                raise InputError(f"{tree_dir}: no tree.glb beside the impostor (--baseline draws the full meshes)")
            mesh = read_glb_mesh(glb)
        out.append(Species(tree_dir.name, imp, mesh, tree_dir))
    return out


def _has_impostor(d: Path) -> bool:
    return (d / "impostor.json").is_file() or (d / "impostor" / "impostor.json").is_file()


def scatter_trees(n: int, area, n_species: int, *, scale=(0.8, 1.25), seed=0) -> np.ndarray:
    """N tree instances over a ``W x D`` ground centred on the origin, blue-noise spaced.

    Returns
    -------
    ndarray, shape (N, 7), float32
        ``x, y (= 0), z, scale, yaw, 0, species`` (the first six are the renderer's instance
        rows, :mod:`treeform.render.instances`).

    Examples
    --------
    >>> t = scatter_trees(100, (50, 50), 2, seed=0)
    >>> t.shape, bool(np.abs(t[:, [0, 2]]).max() <= 25), sorted(set(t[:, 6].tolist()))
    ((100, 7), True, [0.0, 1.0])
    """
    from treeform._shared.rng import as_rng
    from treeform.growth.sampling import blue_noise_points

    rng = as_rng(seed)
    w, d = (float(x) for x in area)
    xz = blue_noise_points(lambda p: np.ones(len(p), bool), ([-w / 2, -d / 2], [w / 2, d / 2]), int(n), seed=rng)
    m = len(xz)
    out = np.zeros((m, 7), np.float32)
    out[:, 0], out[:, 2] = xz[:, 0], xz[:, 1]
    out[:, 3] = rng.uniform(scale[0], scale[1], m)
    out[:, 4] = rng.uniform(0.0, 2 * np.pi, m)
    out[:, 6] = rng.integers(0, max(1, int(n_species)), m)
    return out


def fly_through(area, frames: int, size, fov_y: float, *, height: float = 45.0):
    """Cameras of a straight flight from the ground's near edge toward its centre, looking
    across the forest slightly downward (a view with many trees at every distance)."""
    from treeform.structures.camera import Camera

    w, d = (float(x) for x in area)
    far = float(np.hypot(w, d)) + 200.0
    cams = []
    for k in range(int(frames)):
        t = k / max(1, frames - 1)
        z = -0.5 * d - 10.0 + t * 0.3 * d
        eye = (0.0, height, z)
        target = (0.12 * w * (t - 0.5), 0.0, z + max(5.0 * height, 0.4 * d))
        cams.append(Camera(int(size[0]), int(size[1]), float(fov_y), eye, target, near=0.5, far=far))
    return cams


def select_lod(instances: np.ndarray, species: list, camera, switch_distance: float, *,
               full_px: float = 400.0, card_px: float = 0.0) -> dict:
    """Frustum culling and the LoD switch for one frame.

    Returns
    -------
    dict
        ``visible`` (N,) bool, ``near`` (N,) bool (visible and the crown centre nearer than
        ``switch_distance``), ``count`` (N,) billboards for the near ones, ``card`` (N,) bool
        (visible, not near, and the crown narrower than ``card_px`` pixels on screen).
    """
    from treeform.render.cloud import billboard_count
    from treeform.render.instances import yaw_matrix

    inst = np.asarray(instances, np.float64)
    sp = inst[:, 6].astype(np.int64)
    centers = np.array([s.crown_center for s in species])[sp]
    radius = np.array([s.crown_radius for s in species])[sp] * inst[:, 3]
    world = np.einsum("nij,nj->ni", yaw_matrix(inst[:, 4]), centers * inst[:, 3:4]) + inst[:, :3]
    right, up, fwd = camera.axes()
    rel = world - np.asarray(camera.position)
    x, y, z = rel @ right, rel @ up, rel @ fwd
    ty = math.tan(math.radians(camera.fov_y) / 2)
    tx = ty * camera.width / camera.height
    visible = ((z > camera.near - radius) & (z < camera.far + radius)
               & (np.abs(x) <= z * tx + radius * math.sqrt(1 + tx * tx))
               & (np.abs(y) <= z * ty + radius * math.sqrt(1 + ty * ty)))
    dist = np.linalg.norm(rel, axis=1)
    near = visible & (dist < float(switch_distance))
    diam_px = 2.0 * radius * camera.focal / np.maximum(z, camera.near)
    count = np.where(near, billboard_count(diam_px, full_px=full_px), 0)
    card = visible & ~near & (diam_px < float(card_px))
    return {"visible": visible, "near": near, "count": count, "card": card}


@dataclass
class ForestResult:
    timing: dict
    frames: list
    baseline_frames: list = field(default_factory=list)
    instances: np.ndarray | None = None
    files: dict = field(default_factory=dict)


def _ground(area):
    from treeform.geometry.ground import ground_plane

    w, d = (float(x) * 0.5 + 50.0 for x in area)
    return ground_plane(-w, w, -d, d, _GROUND_RGB)


def render_forest(species_dir, *, out=None, config: ForestConfig | None = None,
                  progress: ProgressCallback | None = None, **overrides) -> ForestResult:
    """Scatter, draw and time a forest of impostor sets (seed 001 §5.1).

    Parameters
    ----------
    species_dir : path
        A folder of tree output folders, each with ``impostor/`` (``treeform impostor``), or
        one such folder.
    out : path, optional
        Output folder; nothing is written with ``out=None``.
    config : ForestConfig, optional
    progress : callable, optional
        ``progress(stage, event, seconds)`` for :data:`FOREST_STAGES`.
    **overrides
        Fields of :class:`ForestConfig`.

    Returns
    -------
    ForestResult
    """
    from treeform.io.outputs import check_out_dir
    from treeform.render import Lighting, Renderer
    from treeform.render.cloud import CloudPass
    from treeform.render.impostor import ReliefPass

    cfg = ForestConfig(**{**asdict(config or ForestConfig()), **overrides}).validate()
    out_dir = check_out_dir(out) if out is not None else None
    timer = StageTimer(progress)
    with timer.stage("load"):
        species = load_species(species_dir, need_mesh=cfg.baseline)
    with timer.stage("scatter"):
        trees = scatter_trees(cfg.trees, cfg.area, len(species), scale=cfg.scale, seed=cfg.seed)
    cams = fly_through(cfg.area, cfg.frames, cfg.size, cfg.fov_y)
    lighting = Lighting(shadow=0.0)
    ground = _ground(cfg.area)
    renderer = Renderer(cams[0], samples=1, background=_SKY, lighting=lighting)
    clouds, reliefs, card_meshes = [], [], []
    frames, baseline_frames, per_frame = [], [], []
    try:
        if cfg.card_px > 0:
            with timer.stage("cards"):
                card_meshes = [_forest_cards(s.impostor, lighting) for s in species]
        for k, s in enumerate(species):
            imp = s.impostor
            clouds.append(CloudPass(imp.rdm, imp.cloud_points, imp.cloud_size, imp.leaflets, color=imp.color,
                                    lighting=lighting, part_id=1000 + k))
            reliefs.append(ReliefPass(imp.rdm, color=imp.color, steps=cfg.relief_steps, refine=cfg.relief_refine,
                                      lighting=lighting, part_id=2000 + k, opacity=imp.opacity,
                                      opacity_steps=cfg.relief_steps))
        with timer.stage("frames"):
            for i, cam in enumerate([cams[0], *cams]):  # the first frame twice: once untimed (shaders compile,
                renderer.camera = cam                    # textures upload on first use), so times are steady-state
                lod = select_lod(trees, species, cam, cfg.switch_distance, full_px=cfg.full_billboards_px,
                                 card_px=cfg.card_px)
                rows = np.column_stack([trees[:, :5], lod["count"]]).astype(np.float32)
                items = [(ground, None)]
                for k, s in enumerate(species):
                    mine = trees[:, 6] == k
                    near, far = mine & lod["near"], mine & lod["visible"] & ~lod["near"] & ~lod["card"]
                    items.append((s.impostor.wood, rows[near]))
                    if card_meshes:
                        items.append((card_meshes[k], rows[mine & lod["card"]]))
                    clouds[k].instances, reliefs[k].instances = rows[near], rows[far]
                stats: dict = {}
                res = renderer.render_scene(items, passes=[*clouds, *reliefs], stats=stats)
                if i == 0:
                    continue
                frames.append(res.color)
                n_vis, n_near, n_card = int(lod["visible"].sum()), int(lod["near"].sum()), int(lod["card"].sum())
                per_frame.append({"ms": round(stats["draw"], 3), "meshes_ms": round(stats["meshes"], 3),
                                  "cloud_ms": round(stats.get("cloud", 0.0), 3),
                                  "relief_ms": round(stats.get("relief", 0.0), 3), "read_ms": round(stats["read"], 3),
                                  "visible": n_vis, "near": n_near, "far": n_vis - n_near - n_card, "cards": n_card,
                                  "billboards": int(lod["count"].sum())})
        if cfg.baseline:
            with timer.stage("baseline"):
                for k, cam in enumerate([cams[0], *cams], start=-1):  # likewise one untimed frame first
                    renderer.camera = cam
                    lod = select_lod(trees, species, cam, cfg.switch_distance)
                    rows = np.column_stack([trees[:, :5], np.zeros(len(trees))]).astype(np.float32)
                    items = [(ground, None)] + [(s.mesh, rows[(trees[:, 6] == j) & lod["visible"]])
                                                for j, s in enumerate(species)]
                    stats = {}
                    res = renderer.render_scene(items, stats=stats)
                    if k < 0:
                        continue
                    baseline_frames.append(res.color)
                    per_frame[k]["baseline_ms"] = round(stats["draw"], 3)
    finally:
        renderer.release()
        for p in (*clouds, *reliefs):
            p.release()
    timing = _timing(cfg, species, per_frame)
    result = ForestResult(timing, frames, baseline_frames, trees)
    if out_dir is not None:
        with timer.stage("export"):
            from treeform.io.images import write_png
            from treeform.io.outputs import StagedOutputs, write_json
            from treeform.methods.envelope.engine import forest_glb, impostor_cards
            from treeform.methods.variations.pipeline import contact_sheet

            cards = [impostor_cards(s.impostor) for s in species] if cfg.glb else None  # GL work: this thread
            page = []
            if cfg.html:
                from treeform.methods.envelope.web import forest_page_writers

                page = forest_page_writers(species, trees, cams[0], switch_distance=cfg.switch_distance,
                                           area=cfg.area, lighting=lighting, sky=_SKY, ground=_GROUND_RGB,
                                           relief_steps=cfg.relief_steps, relief_refine=cfg.relief_refine,
                                           full_px=cfg.full_billboards_px, card_px=cfg.card_px,
                                           cards=card_meshes or None)

            sheet = contact_sheet([f for pair in zip(frames, baseline_frames or frames) for f in
                                   (pair if baseline_frames else pair[:1])],
                                  tile=480, cols=2 if baseline_frames else min(4, len(frames)))
            cfg_json = {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(cfg).items()}
            cfg_json["species"] = [str(s.source) for s in species]

            def frame_writer(img, name):
                def write(d: Path):
                    (d / "frames").mkdir(exist_ok=True)
                    return write_png(img, d / "frames" / name)
                return write

            writers = [frame_writer(f, f"frame_{k:03d}.png") for k, f in enumerate(frames)]
            writers += [frame_writer(f, f"baseline_{k:03d}.png") for k, f in enumerate(baseline_frames)]
            with StagedOutputs(out_dir) as staged:
                staged.submit(*writers,
                              lambda d: write_png(sheet, d / "contact_sheet.png"),
                              lambda d: np.save(d / "instances.npy", trees),
                              lambda d: write_json(d / "timing.json", {**timing, "stages_s": {
                                  k: round(v, 3) for k, v in timer.timings.items()}}),
                              lambda d: write_json(d / "config.json", cfg_json),
                              *([lambda d: forest_glb(species, trees, d / "forest.glb", ground=ground, cards=cards)]
                                if cfg.glb else []), *page)
                result.files = staged.commit()
    timing["stages_s"] = {k: round(v, 3) for k, v in timer.timings.items()}
    return result


_CARD_SIZE = 128
"""Edge in texels of one view of the forest's impostor cards (they stand for crowns a few pixels wide)."""


def _forest_cards(imp, lighting, *, size: int = _CARD_SIZE):
    """A species' impostor cards for the forest's farthest tier: unlit (the light is baked in)."""
    from treeform.methods.envelope.engine import impostor_cards

    return impostor_cards(imp, size=size, lighting=lighting, unlit=True)


def _timing(cfg: ForestConfig, species: list, per_frame: list) -> dict:
    def med(key):
        vals = [f[key] for f in per_frame if key in f]
        return round(float(np.median(vals)), 3) if vals else None

    def rate(n_key, ms_key):
        pairs = [(f[n_key], f[ms_key]) for f in per_frame if f[ms_key] > 0 and f[n_key] > 0]
        return round(float(np.median([n / ms for n, ms in pairs])), 2) if pairs else None

    out = {
        "trees": int(cfg.trees), "area_m": list(cfg.area), "size": list(cfg.size),
        "switch_distance_m": cfg.switch_distance, "frames": len(per_frame),
        "ms_per_frame": med("ms"), "visible_trees": med("visible"), "near_trees": med("near"),
        "far_trees": med("far"), "card_trees": med("cards"),
        "trees_per_ms": {"cloud": rate("near", "cloud_ms"), "relief": rate("far", "relief_ms")},
        "per_frame": per_frame,
        "memory_per_species_bytes": {s.name: s.memory_bytes(card_size=_CARD_SIZE if cfg.card_px > 0 else 0)
                                     for s in species},
    }
    if cfg.baseline:
        out["baseline_ms_per_frame"] = med("baseline_ms")
        out["trees_per_ms"]["mesh"] = rate("visible", "baseline_ms")
        out["speedup"] = round(out["baseline_ms_per_frame"] / max(out["ms_per_frame"], 1e-9), 2)
    from treeform.render.context import get_context

    try:
        info = get_context().info
        out["renderer"] = f"{info.get('GL_RENDERER', '?')}"
    except Exception:  # pragma: no cover - the frames were drawn, so a context exists
        out["renderer"] = "?"
    return out
