"""One synthetic training sample: a grown tree rendered photo-like with exact labels (seed 003 §4.2.1).

:func:`make_sample` turns ``(seed, index)`` into the paper's tuple S = (I, M, R, O, G, P, U):
the RGB image I over a background, the semantic mask M (background / foliage / branches),
the RBV R at levels 1–5, optionally the mesh O, the skeleton graph G, the growth parameters
P and the species id U. Everything random is drawn from ``numpy.random.default_rng([seed,
index])``, so any sample can be regenerated alone, on any worker, bit for bit.

Rendering (the one :class:`~treeform.render.Renderer`): a random camera around the tree
(azimuth 0–360°, elevation −5…30°, field of view 30–55°) framing the whole tree with a
random margin and offset; one to eight directional lights (a sun plus fills, random
directions and tints), a random shadow strength on the sun (shadow map), hemisphere
ambient and a Blinn-Phong highlight; bark and leaf materials with random albedo tint,
normal maps of random strength and random roughness. The image is rendered single-sample
at ``supersample`` × the size and box-filtered, so the alpha of the tree is its exact
pixel coverage; the mask labels a pixel as tree where that coverage is ≥ 1/2 (the majority
class of its covered sub-samples: foliage or branch), so mask and image cannot disagree.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass, field

import numpy as np

from treeform._shared.checks import check_int, check_range
from treeform._shared.errors import InputError
from treeform._shared.timing import ProgressCallback, StageTimer

__all__ = ["LABELS", "Sample", "SampleOptions", "make_sample", "sample_rng"]

LABELS = {"background": 0, "foliage": 1, "branch": 2}
"""Mask values; the same numbering as :class:`~treeform.structures.Segmentation`."""

_BARK_VARIANTS = 6
_LEAF_VARIANTS = 6


@dataclass(frozen=True)
class SampleOptions:
    """What every sample of a dataset shares (stored in the manifest)."""

    size: int = 256
    """Edge of the square image in pixels."""
    species: tuple = ()
    """Species drawn uniformly for each sample; () = all seven presets."""
    supersample: int = 2
    """Render at this multiple of ``size`` and box-filter (anti-aliasing, exact coverage)."""
    lod: str = "medium"
    """Triangle budget of the tree mesh (see :data:`treeform.geometry.LOD_PRESETS`)."""
    mesh: bool = False
    """Also keep the tree mesh (GLB in the shard)."""
    bare: float = 0.0
    """Share of samples drawn leafless (a winter tree: the bark alone, every tree pixel wood).
    Whether a sample is bare is drawn from a stream of its own, so every other sample is the
    same as with 0."""

    def validate(self) -> "SampleOptions":
        from treeform.geometry import LOD_PRESETS
        from treeform.growth.species import SPECIES

        check_int(self.size, "size", 32, 2048)
        check_int(self.supersample, "supersample", 1, 4)
        check_range(self.bare, "bare", 0.0, 1.0)
        unknown = [s for s in self.species if s not in SPECIES]
        if unknown:
            raise InputError(f"species: unknown {', '.join(map(repr, unknown))}; known: {', '.join(SPECIES)}")
        if self.lod not in LOD_PRESETS:
            raise InputError(f"lod: expected one of {', '.join(LOD_PRESETS)}, got {self.lod!r}")
        return self

    @property
    def species_list(self) -> tuple:
        from treeform.growth.species import SPECIES

        return tuple(self.species) or SPECIES


@dataclass
class Sample:
    """One data point; arrays have row 0 at the top of the image.

    Attributes
    ----------
    index : int
    image : ndarray, shape (S, S, 3), uint8
        The photo-like render over its background.
    mask : ndarray, shape (S, S), uint8
        :data:`LABELS`: 0 background, 1 foliage, 2 branch.
    rbv : list of 5 ndarrays, shapes (1, 1), (2, 2), (4, 4), (8, 8), (16, 16)
        Normalised RBV radii at levels 1–5 (layers x sectors; sector 0 starts at the
        camera's right, +X of the canonical pose in which the camera looks from +Z).
    rbv_height, rbv_radius : float
        The RBV's physical height and the radial scale (metres) that undo the normalisation.
    species : str
    species_id : int
        Index in :data:`treeform.growth.species.SPECIES`.
    params : dict
        The growth parameters used (the species' with this sample's jitter).
    skeleton : TreeSkeleton
        The branch graph G, in world coordinates (the camera looks at it from ``meta["camera"]``).
    meta : dict
        Camera, lights, materials, background and counts (JSON-serialisable).
    rgba : ndarray, shape (S, S, 4), uint8
        The tree alone (alpha = coverage): the render before compositing.
    mesh : Mesh
        The rendered tree (stored in shards only when ``SampleOptions.mesh``).
    camera : Camera
        The camera at the image's own size (``S`` x ``S``).
    lighting : Lighting
    store_mesh : bool
    """

    index: int
    image: np.ndarray
    mask: np.ndarray
    rbv: list
    rbv_height: float
    rbv_radius: float
    species: str
    species_id: int
    params: dict
    skeleton: object
    meta: dict
    rgba: np.ndarray = field(repr=False)
    mesh: object = field(default=None, repr=False)
    camera: object = field(default=None, repr=False)
    lighting: object = field(default=None, repr=False)
    store_mesh: bool = False


_BARE_STREAM = 0xBA2E
"""Third word of the stream that decides whether a sample is leafless (:attr:`SampleOptions.bare`)."""


def sample_rng(seed: int, index: int) -> np.random.Generator:
    """The generator of sample ``index`` of a dataset with global ``seed`` (independent streams)."""
    return np.random.default_rng([int(seed), int(index)])


# ------------------------------------------------------------------------------ materials
@functools.lru_cache(maxsize=None)
def _bark_variant(k: int):
    from treeform.geometry import bark_texture, normal_map_from_height, texture_height

    tex = bark_texture(256, seed=1000 + k)
    nrm = normal_map_from_height(texture_height(tex), strength=6.0)
    tex.flags.writeable = nrm.flags.writeable = False
    return tex, nrm


@functools.lru_cache(maxsize=None)
def _leaf_variant(k: int):
    from treeform.geometry import leaf_texture, normal_map_from_height, texture_height

    tex = leaf_texture(128, seed=2000 + k, kind="cluster")
    nrm = normal_map_from_height(texture_height(tex), strength=3.0, wrap=False)
    tex.flags.writeable = nrm.flags.writeable = False
    return tex, nrm


# per part: (texture variants, tint sigma, brightness range, tint floor, roughness range, normal scale range,
# alpha mode, double-sided)
_LOOKS = {
    "bark": (_bark_variant, 0.12, (0.7, 1.25), 0.3, (0.55, 0.95), (0.4, 1.6), "OPAQUE", False),
    "leaves": (_leaf_variant, 0.06, (0.8, 1.15), 0.4, (0.35, 0.85), (0.3, 1.2), "MASK", True),
}


def _materials(mesh, variants: dict, rng) -> dict:
    """Random materials for ``mesh``'s "bark" and "leaves" parts (texture variant per part name), in place.

    Albedo tint, roughness and normal-map strength are drawn per sample (seed 003 §4.2.1:
    "different sets of albedo, normal, and roughness textures"). Returns their description.
    """
    from treeform.structures import Material

    desc = {}
    for part in mesh.parts:
        textures, sigma, bright, floor, rough_range, nscale_range, mode, double = _LOOKS[part.name]
        k = variants[part.name]
        tex, nrm = textures(k)
        tint = np.clip(rng.normal(1.0, sigma, 3) * rng.uniform(*bright), floor, 1.0).round(4)
        rough = round(float(rng.uniform(*rough_range)), 4)
        nscale = round(float(rng.uniform(*nscale_range)), 4)
        part.material = Material(part.name, (*tint.tolist(), 1.0), tex, mode, 0.5, double, rough, 0.0, nrm, nscale)
        desc[part.name] = {"variant": k, "tint": tint.tolist(), "roughness": rough, "normal_scale": nscale}
    return desc


# ------------------------------------------------------------------------------ camera / lights
def _frame(points: np.ndarray, azimuth: float, elevation: float, fov_y: float, size: int, rng):
    """A camera on the orbit (azimuth, elevation) seeing every point, with a random margin and offset."""
    from treeform.structures import Camera

    lo, hi = points.min(0), points.max(0)
    center = 0.5 * (lo + hi)
    az, el = math.radians(azimuth), math.radians(elevation)
    back = np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])
    fwd = -back
    right = np.cross(fwd, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    rel = points - center
    a, b, d = np.abs(rel @ right), np.abs(rel @ up), rel @ fwd
    t = math.tan(math.radians(fov_y) / 2)
    margin = rng.uniform(1.04, 1.3)
    dist = float(np.max(np.maximum(a, b) * margin / t - d))
    dist = max(dist, float(np.max(-d)) + 0.5)
    # random offset within the slack, converted at the nearest depth (never pushes a point out)
    z = dist + d
    ndc_x, ndc_y = (rel @ right) / (t * z), (rel @ up) / (t * z)
    sx = rng.uniform(-1.0 - ndc_x.min(), 1.0 - ndc_x.max()) * 0.9
    sy = rng.uniform(-1.0 - ndc_y.min(), 1.0 - ndc_y.max()) * 0.9
    zmin = float(z.min())
    target = center - (sx * right + sy * up) * t * zmin
    eye = target + back * dist
    reach = float(np.linalg.norm(hi - lo))
    return Camera(size, size, fov_y, tuple(eye), tuple(target), (0.0, 1.0, 0.0),
                  near=max(dist - reach, 0.05), far=dist + reach)


def _unit_dir(azimuth_deg: float, elevation_deg: float) -> list:
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    return [math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)]


def _lighting(rng, shadow_resolution: int = 1024):
    """1–8 directional lights (a sun and fills), shadow strength, ambient and highlight (§4.2.2)."""
    from treeform.render import Lighting

    n = int(rng.integers(1, 9))
    sun = float(rng.uniform(0.55, 1.0))
    warm = rng.uniform(-0.08, 0.08)
    sun_col = np.array([1.0 + warm, 1.0, 1.0 - warm]) * sun
    sun_dir = _unit_dir(rng.uniform(0, 360), rng.uniform(15, 75))
    fills = []
    for _ in range(n - 1):
        c = rng.uniform(0.04, 0.22) * np.clip(rng.normal(1.0, 0.08, 3), 0.7, 1.3)
        fills.append((_unit_dir(rng.uniform(0, 360), rng.uniform(-20, 80)), c.round(4).tolist()))
    sky = rng.uniform(0.3, 0.55) * np.array([0.95, 0.98, 1.06])
    ground = sky * rng.uniform(0.35, 0.6) * np.array([1.02, 1.0, 0.9])
    lt = Lighting(direction=sun_dir, key=tuple(sun_col.round(4)), sky=tuple(sky.round(4)),
                  ground=tuple(ground.round(4)), lights=tuple((tuple(d), tuple(c)) for d, c in fills),
                  shadow=float(round(rng.uniform(0.0, 1.0), 4)), shadow_resolution=int(shadow_resolution),
                  specular=float(round(rng.uniform(0.0, 0.35), 4)))
    desc = {"lights": 1 + len(fills), "sun_direction": [round(x, 5) for x in sun_dir],
            "sun_color": sun_col.round(4).tolist(), "shadow": lt.shadow, "specular": lt.specular,
            "sky": sky.round(4).tolist(), "ground": ground.round(4).tolist(),
            "fills": [{"direction": [round(x, 5) for x in d], "color": c} for d, c in fills]}
    return lt, desc


# ------------------------------------------------------------------------------ labels
def _downsample(color: np.ndarray, labels: np.ndarray, f: int):
    """Box-filter a single-sample render ``f``× down: RGBA with alpha = coverage, and the label per pixel.

    A pixel is tree where at least half its sub-samples are covered; its label is the more
    frequent of foliage and branch among them (branch on a tie: thin twigs stay visible).
    """
    h, w = labels.shape[0] // f, labels.shape[1] // f
    cov = (labels > 0).reshape(h, f, w, f)
    n = cov.sum(axis=(1, 3))
    wood = (labels == LABELS["branch"]).reshape(h, f, w, f).sum(axis=(1, 3))
    rgb = color[..., :3].astype(np.float64) * (labels > 0)[..., None]
    rgb = rgb.reshape(h, f, w, f, 3).sum(axis=(1, 3))
    out = np.zeros((h, w, 4), np.uint8)
    out[..., :3] = np.clip(np.rint(rgb / np.maximum(n, 1)[..., None]), 0, 255).astype(np.uint8)
    out[..., 3] = np.rint(n * 255.0 / (f * f)).astype(np.uint8)
    tree = 2 * n >= f * f
    mask = np.where(tree, np.where(2 * wood >= n, LABELS["branch"], LABELS["foliage"]), LABELS["background"])
    return out, mask.astype(np.uint8)


def canonical_rbv(skeleton, azimuth_deg: float):
    """RBV levels 1–5 of the tree turned so that the camera looks from +Z (seed 003 §4.2.1)."""
    from treeform.structures import RadialBoundingVolume, TreeSkeleton

    a = math.radians(azimuth_deg)
    c, s = math.cos(-a), math.sin(-a)
    rot = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    p = (skeleton.positions - skeleton.positions[0]) @ rot.T + skeleton.positions[0]
    turned = TreeSkeleton(p, skeleton.parent, skeleton.radius, skeleton.order, skeleton.age)
    rbv = RadialBoundingVolume.from_skeleton(turned, level=5).normalized()
    return rbv.levels(), float(rbv.height_scale), float(rbv.radial_scale)


# ------------------------------------------------------------------------------ sample
def make_sample(seed: int, index: int, options: SampleOptions | None = None, *, backgrounds=None,
                progress: ProgressCallback | None = None) -> Sample:
    """Generate sample ``index`` of the dataset with global ``seed`` (seed 003 §4.2.1).

    Parameters
    ----------
    seed, index : int
        Same pair (and options) -> identical sample, whichever process makes it.
    options : SampleOptions, optional
    backgrounds : BackgroundPool, optional
        Default: procedural backgrounds only.
    progress : callable, optional
        ``progress(stage, event, seconds)`` for the stages grow, leaves, mesh, render, labels,
        background and rbv.

    Returns
    -------
    Sample

    Raises
    ------
    InputError
        Bad options.
    RenderError
        No OpenGL context.
    """
    from treeform.dataset.backgrounds import BackgroundPool
    from treeform.geometry import LOD_PRESETS, foliage_budget, tree_mesh
    from treeform.growth.leaves import twig_foliage, twig_nodes
    from treeform.growth.phenomenological import GrowthParameters, grow
    from treeform.growth.species import SPECIES, load_species, load_species_appearance
    from treeform.render import Renderer

    opts = (options or SampleOptions()).validate()
    if backgrounds is None:
        backgrounds = BackgroundPool()
    timer = StageTimer(progress)
    rng = sample_rng(seed, index)
    species = str(opts.species_list[int(rng.integers(len(opts.species_list)))])

    # -- tree: growth with a little jitter of size, leaves on the twigs
    base = load_species(species)
    params = GrowthParameters.from_dict({"age": max(4, base.age + int(rng.integers(-2, 2)))}, base=base)
    tree_seed = int(rng.integers(2**31))
    with timer.stage("grow"):
        skeleton = grow(params, seed=tree_seed)
    skeleton.meta["species"] = species
    look = load_species_appearance(species)
    leaf_rgb = np.clip(np.asarray(look.leaf_color) * rng.normal(1.0, 0.08, 3) * rng.uniform(0.8, 1.2), 0.02, 1.0)
    with timer.stage("leaves"):
        leaf_size, per_twig = look.leaf_size * rng.uniform(0.85, 1.15), rng.uniform(2.0, 4.0)
        n_leaves = int(round(per_twig * len(twig_nodes(skeleton))))
        if LOD_PRESETS[opts.lod] is not None:  # only the clusters the budget keeps, enlarged as the LOD would
            n_leaves, factor = foliage_budget(skeleton, n_leaves, max_triangles=LOD_PRESETS[opts.lod])
            leaf_size *= factor
        foliage = twig_foliage(skeleton, leaf_color=leaf_rgb, size=leaf_size, leaves=n_leaves, seed=rng)
    leaf_k, bark_k = int(rng.integers(_LEAF_VARIANTS)), int(rng.integers(_BARK_VARIANTS))
    with timer.stage("mesh"):
        mesh = tree_mesh(skeleton, foliage, max_triangles=LOD_PRESETS[opts.lod],
                         leaf_texture=_leaf_variant(leaf_k)[0], seed=tree_seed)
    materials = _materials(mesh, {"bark": bark_k, "leaves": leaf_k}, rng)
    share = float(opts.bare)
    bare = share > 0 and bool(np.random.default_rng([int(seed), int(index), _BARE_STREAM]).random() < share)
    if bare:  # the same tree in winter: its leaves dropped after every draw of the sample's own stream
        mesh = type(mesh)([p for p in mesh.parts if p.name == "bark"])
        foliage = []

    # -- camera, lights, render
    azimuth, elevation, fov = rng.uniform(0.0, 360.0), rng.uniform(-5.0, 30.0), rng.uniform(30.0, 55.0)
    pts = [p.positions for p in mesh.parts if p.n_vertices]
    f = int(opts.supersample)
    camera = _frame(np.concatenate(pts).astype(np.float64), azimuth, elevation, fov, opts.size * f, rng)
    # a shadow-map texel about the size of a rendered pixel (the tree fills most of the frame)
    lighting, light_desc = _lighting(rng, shadow_resolution=max(256, opts.size * f))
    with timer.stage("render"):
        renderer = Renderer(camera, samples=1, lighting=lighting)
        try:
            res = renderer.render(mesh)
        finally:
            renderer.release()
    with timer.stage("labels"):
        part_label = np.array([LABELS["branch"] if p.name == "bark" else LABELS["foliage"] for p in mesh.parts]
                              + [LABELS["background"]], np.uint8)
        labels = part_label[res.part]  # part -1 -> the trailing background entry
        rgba, mask = _downsample(res.color, labels, f)

    # -- background, composite, sensor noise
    with timer.stage("background"):
        bg, bg_desc = backgrounds.sample(opts.size, rng)
        a = rgba[..., 3:4].astype(np.float64) / 255.0
        img = rgba[..., :3] * a + bg * (1.0 - a)
        noise = float(rng.uniform(0.0, 2.5))
        img = img + rng.normal(0.0, noise, img.shape)
        image = np.clip(np.rint(img), 0, 255).astype(np.uint8)

    with timer.stage("rbv"):
        rbv, rbv_h, rbv_r = canonical_rbv(skeleton, azimuth)
    cam_out = {"azimuth_deg": round(float(azimuth), 4), "elevation_deg": round(float(elevation), 4),
               "fov_y_deg": round(float(fov), 4), "position": [round(float(x), 5) for x in camera.position],
               "target": [round(float(x), 5) for x in camera.target]}
    meta = {"camera": cam_out, "lighting": light_desc, "materials": materials, "background": bg_desc,
            "noise_sigma": round(noise, 4), "tree_seed": tree_seed, "nodes": skeleton.n_nodes,
            "leaves": len(foliage), **({"bare": True} if bare else {}), "triangles": mesh.n_triangles,
            "coverage": round(float((mask > 0).mean()), 5)}
    return Sample(index=int(index), image=image, mask=mask, rbv=rbv, rbv_height=rbv_h, rbv_radius=rbv_r,
                  species=species, species_id=SPECIES.index(species), params=params.to_dict(), skeleton=skeleton,
                  meta=meta, rgba=rgba, mesh=mesh, camera=dataclasses.replace(camera, width=opts.size, height=opts.size), lighting=lighting,
                  store_mesh=opts.mesh)
