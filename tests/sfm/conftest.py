"""A tiny rendered capture for the SfM tests: textured boxes on paved ground, walls around, photos.

One scenery :class:`MeshPart` with one texture atlas (the ground in one quadrant, a 512² tile
per box and per wall); 12 views at 400 x 300 on a circle (3 m radius) at eye height (1.6 m)
looking at the boxes; each JPEG carries its 35 mm-equivalent focal length in EXIF, and one
photo is stored rotated a quarter turn counter-clockwise with EXIF orientation 6 (upright
after ``exif_transpose``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

N_VIEWS = 12
SIZE = (400, 300)  # pixels of the photos
FOV_Y = 50.0
RADIUS = 3.0  # metres from the centre to each camera
EYE = 1.6  # camera height: a phone at eye level
TARGET = (0.0, 0.2, 0.0)
GROUND = 10.0  # side of the ground square
MOSAIC = 3000  # paving stones on the ground ...
MOSAIC_SIZE = (4, 30)  # ... of these sizes in texels (1024 texels over the ground)
BOX_SCALE = 0.4  # boxes of 0.3 .. 0.6 m, 0.5 .. 1 m from the centre
WALLS = 6  # a hexagon of walls ...
WALL_RADIUS = 5.0
WALL_HEIGHT = 2.5
SS = 2  # supersampling: box-filtered 2x renders keep the oblique ground sharper (mipmaps are isotropic)
ROTATED = "v03.jpg"  # stored a quarter turn counter-clockwise, EXIF orientation 6


def _texture(rng, n: int, base, spread: float, sigmas=(0.8, 2.5, 8.0, 24.0)) -> np.ndarray:
    """An (n, n, 4) opaque texture of coloured noise summed over ``sigmas`` (distinctive for SIFT)."""
    import cv2

    noise = np.zeros((n, n, 3), np.float32)
    for sigma in sigmas:
        layer = cv2.GaussianBlur(rng.normal(size=(n, n, 3)).astype(np.float32), (0, 0), sigma,
                                 borderType=cv2.BORDER_REFLECT)
        noise += layer / max(float(layer.std()), 1e-6)
    noise = (noise - noise.mean((0, 1))) / noise.std((0, 1))
    img = np.clip(np.asarray(base, np.float32) + spread * noise, 0, 255).astype(np.uint8)
    return np.dstack([img, np.full((n, n), 255, np.uint8)])


def _mosaic(rng, n: int, count: int) -> np.ndarray:
    """An (n, n, 4) texture of random coloured rectangles over noise (paving: sharp corners that
    SIFT finds again from oblique views of the ground)."""
    img = _texture(rng, n, (110, 115, 70), 40)
    for _ in range(count):
        w, h = (int(v) for v in rng.integers(MOSAIC_SIZE[0], MOSAIC_SIZE[1], 2))
        x, y = (int(v) for v in rng.integers(0, n - 8, 2))
        img[y:y + h, x:x + w, :3] = rng.integers(20, 236, 3)
    return img


def scene_mesh(seed: int = 0):
    """The scenery: a paved ground square, six boxes and a ring of walls; one MeshPart, one 2048² atlas."""
    from treeform.structures.mesh import Material, Mesh, MeshPart

    rng = np.random.default_rng(seed)
    atlas = np.zeros((2048, 2048, 4), np.uint8)
    atlas[:1024, :1024] = _mosaic(rng, 1024, MOSAIC)
    tiles = [(r, c) for r in range(4) for c in range(4) if not (r < 2 and c < 2)]
    quads = []  # (4 corners, 4 uvs)
    S = GROUND / 2
    quads.append(([[-S, 0, S], [S, 0, S], [S, 0, -S], [-S, 0, -S]],
                  [[0.001, 0.001], [0.499, 0.001], [0.499, 0.499], [0.001, 0.499]]))
    for k in range(6):
        r, c = tiles[k]
        atlas[r * 512:(r + 1) * 512, c * 512:(c + 1) * 512] = _texture(rng, 512, rng.uniform(60, 200, 3), 50)
        a, d = 2 * math.pi * k / 6 + 0.3, BOX_SCALE * (1.2 + 1.3 * (k % 3) / 2)
        sx, sy, sz = BOX_SCALE * rng.uniform(0.8, 1.6, 3) * [1.0, rng.uniform(0.6, 1.2), 1.0]
        rot = rng.uniform(0, math.pi)
        R = np.array([[math.cos(rot), 0, math.sin(rot)], [0, 1, 0], [-math.sin(rot), 0, math.cos(rot)]])
        corners = np.array([[x, y, z] for y in (0, sy) for z in (-sz / 2, sz / 2) for x in (-sx / 2, sx / 2)])
        corners = corners @ R.T + [d * math.sin(a), 0.0, d * math.cos(a)]
        # each side its own quadrant of the box's tile (a texture repeated on two faces would
        # make false matches); the top one texel (a plain colour)
        for q, f in enumerate(((0, 1, 5, 4), (1, 3, 7, 5), (3, 2, 6, 7), (2, 0, 4, 6))):
            u0, v0, e = c / 4 + (q % 2) / 8 + 0.002, r / 4 + (q // 2) / 8 + 0.002, 0.125 - 0.004
            quads.append((corners[list(f)], [[u0, v0 + e], [u0 + e, v0 + e], [u0 + e, v0], [u0, v0]]))
        uc, vc = c / 4 + 0.125, r / 4 + 0.125
        quads.append((corners[[4, 5, 7, 6]], [[uc, vc]] * 4))
    for k in range(WALLS):  # a ring of walls facing inward (the backdrop of a park)
        r, c = tiles[6 + k]
        atlas[r * 512:(r + 1) * 512, c * 512:(c + 1) * 512] = _texture(rng, 512, rng.uniform(60, 200, 3), 55)
        u0, v0, e = c / 4 + 0.002, r / 4 + 0.002, 0.25 - 0.004
        a0, a1 = 2 * math.pi * k / WALLS, 2 * math.pi * (k + 1) / WALLS
        h = WALL_HEIGHT
        p0 = [WALL_RADIUS * math.sin(a0), 0.0, WALL_RADIUS * math.cos(a0)]
        p1 = [WALL_RADIUS * math.sin(a1), 0.0, WALL_RADIUS * math.cos(a1)]
        quads.append(([p0, p1, [p1[0], h, p1[2]], [p0[0], h, p0[2]]],
                      [[u0, v0 + e], [u0 + e, v0 + e], [u0 + e, v0], [u0, v0]]))
    P = np.concatenate([np.asarray(q[0], np.float32) for q in quads])
    UV = np.concatenate([np.asarray(q[1], np.float32) for q in quads])
    nrm = []
    for q in quads:
        q0 = np.asarray(q[0], np.float64)
        n = np.cross(q0[1] - q0[0], q0[2] - q0[0])
        nrm.append(np.tile(n / np.linalg.norm(n), (4, 1)))
    idx = np.concatenate([np.array([[0, 1, 2], [0, 2, 3]]) + 4 * i for i in range(len(quads))])
    part = MeshPart(P, np.concatenate(nrm).astype(np.float32), UV, None, idx.astype(np.uint32),
                    Material("scenery", texture=atlas, double_sided=True), "scenery")
    return Mesh([part])


def view_cameras() -> dict:
    """{file name: Camera} of the capture (the truth)."""
    from treeform.structures import Camera

    cams = {}
    for k in range(N_VIEWS):
        az = 2 * math.pi * k / N_VIEWS
        eye = (RADIUS * math.sin(az), EYE, RADIUS * math.cos(az))
        cams[f"v{k:02d}.jpg"] = Camera(SIZE[0], SIZE[1], FOV_Y, eye, TARGET, near=0.1, far=100.0)
    return cams


def focal_35mm(cam) -> int:
    """The camera's focal as EXIF FocalLengthIn35mmFilm (diagonal definition, whole mm)."""
    return int(round(cam.focal * math.hypot(36, 24) / math.hypot(cam.width, cam.height)))


def save_jpeg(path, rgb: np.ndarray, *, f35: int | None = None, orientation: int | None = None) -> None:
    from PIL import Image

    exif = Image.Exif()
    if orientation is not None:
        exif[0x0112] = orientation
    if f35 is not None:
        exif.get_ifd(0x8769)[0xA405] = f35
    Image.fromarray(rgb).save(path, quality=95, exif=exif)


def render_capture(folder) -> dict:
    """Render the capture into ``folder``; returns the true cameras ``{name: Camera}``."""
    from treeform.render import Lighting, Renderer
    from treeform.structures import Camera

    mesh = scene_mesh()
    cams = view_cameras()
    for name, cam in cams.items():
        big = Camera(SS * cam.width, SS * cam.height, cam.fov_y, cam.position, cam.target, near=0.1, far=100.0)
        r = Renderer(big, samples=1, background=(0.6, 0.75, 0.95, 1.0), lighting=Lighting())
        try:
            res = r.render(mesh)
        finally:
            r.release()
        im = res.rgb((150, 190, 240)).astype(np.float32)
        im = im.reshape(cam.height, SS, cam.width, SS, 3).mean((1, 3)).round().astype(np.uint8)
        if name == ROTATED:  # stored a quarter turn counter-clockwise; orientation 6 turns it back clockwise
            save_jpeg(folder / name, np.ascontiguousarray(np.rot90(im, 1)), f35=focal_35mm(cam), orientation=6)
        else:
            save_jpeg(folder / name, im, f35=focal_35mm(cam))
    return cams


@pytest.fixture(scope="session")
def capture(tmp_path_factory):
    """Folder of the rendered capture and its true cameras: ``(folder, {name: Camera})``."""
    from treeform._shared.errors import RenderError

    folder = tmp_path_factory.mktemp("capture")
    try:
        cams = render_capture(folder)
    except RenderError as exc:
        pytest.skip(str(exc))
    return folder, cams


@pytest.fixture(scope="session")
def colmap():
    """pycolmap, or a skip where it is not installed (zlib is loaded first: see
    :func:`treeform.sfm.colmap.import_pycolmap`)."""
    import zlib  # noqa: F401

    import cv2  # noqa: F401

    return pytest.importorskip("pycolmap")


@pytest.fixture(scope="session")
def sfm_result(capture, colmap):
    """``run_sfm`` on the capture (seed 0)."""
    from treeform.sfm import load_photos, run_sfm

    return run_sfm(load_photos(capture[0]), seed=0)
