"""preview.png's parts: framing cameras, panel windows and labelled strips (no OpenGL needed)."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.report import PREVIEW_LABELS, compose_strip, photo_window, preview_cameras, preview_windows
from treeform.structures import Camera


def crown_points(seed=0, n=4000, offset=(0.0, 0.0, 0.0)):
    """A lopsided tree: trunk on the Y axis, an ellipsoidal crown pushed toward -X and +Z."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    crown = d * [6.0, 4.0, 3.0] + [-3.0, 9.0, 1.5]
    trunk = np.column_stack([np.zeros(50), np.linspace(0, 6, 50), np.zeros(50)])
    return np.concatenate([trunk, crown]) + offset


def inside_with_margin(cam: Camera, pts, margin: float) -> bool:
    uvz = cam.project(pts)
    return bool(np.all(uvz[:, 2] > cam.near) and np.all(uvz[:, 2] < cam.far)
                and np.all(uvz[:, 0] >= margin) and np.all(uvz[:, 0] <= cam.width - margin)
                and np.all(uvz[:, 1] >= margin) and np.all(uvz[:, 1] <= cam.height - margin))


def test_fitted_cameras_frame_every_point_and_fill_the_view():
    pts = crown_points()
    cams = preview_cameras(pts, fov_y=35.0, size=400)
    assert set(cams) == {"front", "side", "top"}
    for name, cam in cams.items():
        # every point in view with a margin of background (4 % of 400 px = 16 px, allow rounding)
        assert inside_with_margin(cam, pts, 15.0), name
        uv = cam.project(pts)[:, :2]
        fill = max(np.ptp(uv[:, 0]) / cam.width, np.ptp(uv[:, 1]) / cam.height)
        assert fill > 0.8, (name, fill)
    f, s, t = cams["front"], cams["side"], cams["top"]
    assert f.height == 400 and s.height == f.height == t.height
    # front looks along -Z, side along -X, top straight down with -Z up the image
    np.testing.assert_allclose(f.axes()[2], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(s.axes()[2], [-1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(t.axes()[2], [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(t.axes()[1], [0, 0, -1], atol=1e-12)
    # front and side share one scale: same focal length and distance, the same height
    assert s.focal == pytest.approx(f.focal)
    dist = lambda c: np.linalg.norm(np.subtract(c.position, c.target))  # noqa: E731
    assert dist(s) == pytest.approx(dist(f)) and s.target[1] == pytest.approx(f.target[1])


def test_a_photo_camera_is_widened_evenly_and_its_frame_stays_pixel_for_pixel():
    pts = crown_points(offset=(0.0, 0.0, 0.0))
    # a photo that cuts the crown off on the left and the trunk off at the bottom
    photo = Camera(300, 400, 40.0, (2.0, 10.0, 22.0), (2.0, 10.0, 0.0), (0, 1, 0), near=5.0, far=60.0)
    uv = photo.project(pts)
    assert uv[:, 0].min() < 0 and uv[:, 1].max() > 400  # the tree spills out of the photo
    cams = preview_cameras(pts, front=photo)
    f = cams["front"]
    assert f.position == photo.position and f.target == photo.target and f.focal == pytest.approx(photo.focal)
    assert (f.width - photo.width) % 2 == 0 and (f.height - photo.height) % 2 == 0
    assert f.width > photo.width and f.height > photo.height
    assert inside_with_margin(f, pts, 15.0)
    assert f.near <= photo.near and f.far >= photo.far
    rows, cols = photo_window(f, photo)
    np.testing.assert_allclose(f.project(pts)[:, :2] - [cols.start, rows.start], uv[:, :2], atol=1e-9)
    for name in ("side", "top"):
        assert inside_with_margin(cams[name], pts, 15.0), name
    assert cams["side"].height == f.height and cams["side"].focal == pytest.approx(f.focal)
    # a photo that already shows all of the tree keeps its size
    wide = Camera(800, 800, 60.0, (-3.0, 8.0, 40.0), (-3.0, 8.0, 0.0), (0, 1, 0), near=5.0, far=80.0)
    assert (preview_cameras(pts, front=wide)["front"].width, preview_cameras(pts, front=wide)["front"].height) \
        == (800, 800)


def test_preview_cameras_rejects_bad_input():
    with pytest.raises(InputError, match="points"):
        preview_cameras(np.zeros((0, 3)))
    with pytest.raises(InputError, match="points"):
        preview_cameras(np.array([[0, np.nan, 0.0]]))
    with pytest.raises(InputError, match="front"):
        preview_cameras(crown_points(), front="camera")
    with pytest.raises(InputError, match="fov_y"):
        preview_cameras(crown_points(), fov_y=0)


def test_windows_keep_the_silhouette_with_a_margin_and_share_rows():
    front = np.zeros((200, 150), bool)
    front[40:170, 50:90] = True
    side = np.zeros((200, 120), bool)
    side[30:160, 20:100] = True
    top = np.zeros((200, 200), bool)
    top[60:140, 30:170] = True
    w = preview_windows({"front": front, "side": side, "top": top}, margin=5)
    assert w["front"][0] == w["side"][0] == slice(25, 175)  # union of both silhouettes' rows
    assert w["front"][1] == slice(45, 95) and w["side"][1] == slice(15, 105)
    assert w["top"] == (slice(55, 145), slice(25, 175))
    # the photo's frame stays in the front panel; windows never leave the image
    w = preview_windows({"front": front, "side": side}, keep=(slice(10, 190), slice(0, 150)), margin=20)
    assert w["front"] == (slice(0, 200), slice(0, 150)) and w["side"][0] == slice(0, 200)


def test_compose_strip_labels_every_panel():
    tiles = [np.full((100, 80, 3), 255, np.uint8), np.full((50, 100, 3), 255, np.uint8)]
    plain = compose_strip(tiles, height=120, background=(255, 255, 255))
    labelled = compose_strip(tiles, labels=["photo", PREVIEW_LABELS["side"]], height=120,
                             background=(255, 255, 255))
    band = labelled.shape[0] - plain.shape[0]
    assert band >= 12 and labelled.shape[1] == plain.shape[1]
    # dark text in the band above each panel, nothing dark in the white panels themselves
    x = 6
    for t in tiles:
        w = round(t.shape[1] * 120 / t.shape[0])
        assert (labelled[6:6 + band, x:x + w].min(axis=2) < 100).sum() > 20
        assert labelled[6 + band + 1:6 + band + 119, x + 1:x + w - 1].min() == 255
        x += w + 6
    with pytest.raises(InputError, match="labels"):
        compose_strip(tiles, labels=["one"])


def test_a_tile_narrower_than_its_label_is_widened_so_labels_do_not_overlap():
    """A side view of a slender tree is narrower than "side (from the right)": its panel widens
    (the picture centred) so the label ends before the next panel's starts."""
    narrow = np.zeros((120, 12, 3), np.uint8)  # dark: 12 px wide at height 120
    tiles = [narrow, np.full((120, 120, 3), 255, np.uint8)]
    out = compose_strip(tiles, labels=[PREVIEW_LABELS["side"], PREVIEW_LABELS["top"]], height=120,
                        background=(255, 255, 255))
    band = out.shape[0] - 120 - 12
    ink = (out[6:6 + band].min(axis=2) < 100).any(axis=0)  # columns with label text
    runs = np.flatnonzero(np.diff(np.r_[0, ink.astype(np.int8), 0]))  # label starts and ends
    gaps = runs[2::2] - runs[1:-1:2]
    assert out.shape[1] > 12 + 120 + 3 * 6 and gaps.max() >= 6  # a clear gap between the two labels
    body = out[6 + band + 1:6 + band + 119]
    dark = np.flatnonzero((body.max(axis=2) < 50).any(axis=0))
    assert len(dark) and dark.max() - dark.min() + 1 == 12  # the picture kept its own width
