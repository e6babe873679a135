"""Image-based tree variations (seed 000): exemplars, synthesis, colour and histogram transfer."""

from pathlib import Path

import numpy as np
import pytest

from treeform._shared.errors import InputError, NoTreeFoundError
from treeform.contour import fill_contour, longest_exterior_contour, pin_points
from treeform.methods.variations import (
    VariationsConfig,
    match_histograms,
    morph,
    normalize_rgba,
    process_exemplar,
    read_rgba,
    synthesize,
    vary,
)
from treeform.methods.variations.pipeline import load_exemplar, process_library

ROOT = Path(__file__).resolve().parents[2]
BILLBOARDS = ROOT.parent / "shared" / "data" / "billboards"
SIZE = 384  # small exemplars keep the tests fast; the defaults (1024) are benchmarked


def _need_data():
    if not BILLBOARDS.is_dir():
        pytest.skip("../shared/data/billboards is not available")


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    _need_data()
    return process_library(BILLBOARDS, cache_dir=tmp_path_factory.mktemp("cache"), size=SIZE)


def _by_name(lib, name):
    return lib.exemplars[lib.names.index(name)]


def test_first_resampled_point_is_the_bottom_pin_in_every_exemplar(library):
    assert len(library) == 37
    for ex in library.exemplars:
        assert ex.resampled.shape == (2000, 2) and ex.simplified.shape == (20, 2)
        mask = ex.labels > 0
        c = longest_exterior_contour(mask)
        b = c[pin_points(c, baseline=None).b]
        assert np.array_equal(ex.resampled[0], b), ex.name  # Cr[0] = B, the lowest contour point
        assert b[1] == c[:, 1].max()
    assert sum(e.has_trunk for e in library.exemplars) >= 25  # most library trees show a trunk


def test_normalisation(library):
    ex = _by_name(library, "cesium_tree_billboard.png")
    a = ex.rgba
    assert a.shape == (SIZE, SIZE, 4)
    assert (a[a[..., 3] < 128] == 0).all()  # transparent pixels are black
    rows = np.nonzero((a[..., 3] >= 128).any(1))[0]
    m = SIZE // 64  # default margin; a tall tree fills the height (within resampling blur)
    assert abs(rows.min() - m) <= 2 and abs(rows.max() - (SIZE - 1 - m)) <= 2
    with pytest.raises(NoTreeFoundError):
        normalize_rgba(np.zeros((20, 20, 4), np.uint8))
    with pytest.raises(InputError):
        normalize_rgba(np.zeros((20, 20, 3), np.uint8))


def test_no_opaque_pixel_outside_the_synthesised_contour(library):
    rng = np.random.default_rng(0)
    for _ in range(6):
        j = rng.choice(len(library), size=3, replace=False)
        w = rng.dirichlet(np.ones(3))
        syn = synthesize([library.exemplars[i] for i in j], w, colour_weights=rng.dirichlet(np.ones(3)))
        inside = fill_contour(syn.contour, syn.mask.shape)
        assert not (syn.rgba[..., 3] > 0)[~inside].any()
        assert (syn.rgba[..., 3] > 0).sum() > 0.3 * inside.sum()


def test_morph_ends_reproduce_the_exemplars(library):
    a = _by_name(library, "cesium_tree_billboard.png")
    b = _by_name(library, "savanna-trees_row3_col0.png")
    res = morph(a, b, steps=3, size=SIZE)
    assert np.array_equal(res.contours[0], a.resampled) and np.array_equal(res.contours[-1], b.resampled)
    for frame, ex in ((res.frames[0], a), (res.frames[-1], b)):
        # inside the overall contour the identity warp reproduces the exemplar (opaque
        # bits outside it, disconnected from the tree, are not part of the synthesis)
        inside = fill_contour(ex.resampled, (SIZE, SIZE))
        assert np.abs(frame[..., 3].astype(int) - ex.rgba[..., 3])[inside].max() <= 1
        assert ((ex.rgba[..., 3] > 0) & ~inside).sum() < 0.1 * (ex.rgba[..., 3] > 0).sum()
        vis = (frame[..., 3] > 32) & (ex.rgba[..., 3] > 32)
        assert np.abs(frame[..., :3].astype(int) - ex.rgba[..., :3])[vis].max() <= 2
    mid = res.frames[1]
    assert 0.3 < ((mid[..., 3] > 0) & (a.rgba[..., 3] > 0)).sum() / max(1, (mid[..., 3] > 0).sum()) < 1


def test_colour_transfer_takes_colours_only_from_opaque_samples(library):
    a = _by_name(library, "coniferous_row3_col0.png")
    b = _by_name(library, "tropical-alt_row3_col6.png")
    syn = synthesize([a, b], [0.5, 0.5], colour_weights=[1.0, 0.0])
    al = syn.rgba[..., 3]
    assert (syn.rgba[al == 0] == 0).all()
    # colour weight 0 for b: wherever a's sample is transparent, the colour still comes from b
    assert (al > 0).sum() > 0


def test_histogram_transfer_matches_the_reference_quantiles():
    rng = np.random.default_rng(3)
    img = np.zeros((120, 100, 4), np.uint8)
    img[..., :3] = rng.normal(90, 20, (120, 100, 3)).clip(0, 255)
    img[..., 3] = 255
    img[:30] = (255, 0, 255, 0)  # transparent pixels: ignored
    ref = np.zeros((80, 90, 4), np.uint8)
    ref[..., 0] = rng.normal(180, 30, (80, 90)).clip(0, 255)
    ref[..., 1] = rng.uniform(20, 120, (80, 90))
    ref[..., 2] = rng.gamma(2.0, 20.0, (80, 90)).clip(0, 255)
    ref[..., 3] = 255
    ref[:10, :, :3] = 0
    ref[:10, :, 3] = 0  # transparent black in the reference is ignored too
    out = match_histograms(img, ref)
    assert np.array_equal(out[..., 3], img[..., 3]) and np.array_equal(out[:30], img[:30])
    qs = np.linspace(0.05, 0.95, 19)
    for c in range(3):
        got = np.quantile(out[30:, :, c], qs)
        want = np.quantile(ref[10:, :, c], qs)
        assert np.abs(got - want).max() <= 3, c
    rgb_ref = ref[10:, :, :3]
    assert np.abs(np.quantile(match_histograms(img, rgb_ref)[30:, :, 0], qs)
                  - np.quantile(rgb_ref[..., 0], qs)).max() <= 3


def test_same_seed_same_png_bytes(library, tmp_path):
    sub = library.paths[:6]
    cfg = VariationsConfig(size=SIZE, tile=64)
    r1 = vary(sub, n=3, out=tmp_path / "a", seed=5, config=cfg, cache_dir=library.cache_dir)
    r2 = vary(sub, n=3, out=tmp_path / "b", seed=5, config=cfg, cache_dir=library.cache_dir)
    r3 = vary(sub, n=3, seed=6, config=cfg, cache_dir=library.cache_dir)
    names = sorted(p.name for p in (tmp_path / "a").iterdir())
    assert names == ["config.json", "contact_sheet.png", "variation_000.png", "variation_001.png",
                     "variation_002.png"]
    for name in names:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    assert any(not np.array_equal(x, y) for x, y in zip(r1.images, r3.images))
    for rec in r1.records:
        assert len(rec["exemplars"]) == 2 and 0.3 <= rec["weights"][0] <= 0.7
    assert r2.records == r1.records


def test_variations_of_a_given_tree_weight_it_higher(library):
    t = library.paths[library.names.index("cesium_tree_billboard.png")]
    res = vary(library, n=4, from_tree=t, seed=1, size=SIZE)
    for rec in res.records:
        assert rec["exemplars"][0] == "cesium_tree_billboard.png"
        assert 0.55 <= rec["weights"][0] <= 0.8 and 0.55 <= rec["colour_weights"][0] <= 0.8


def test_cache_is_used_and_keyed_by_content(library, tmp_path):
    src = library.paths[0]
    ex1, hit1 = load_exemplar(src, cache_dir=library.cache_dir, size=SIZE)
    assert hit1 and np.array_equal(ex1.resampled, library.exemplars[0].resampled)
    ex2, hit2 = load_exemplar(src, cache_dir=library.cache_dir, size=SIZE, simplified_points=30)
    assert not hit2 and ex2.simplified.shape == (30, 2)


def test_bad_inputs(tmp_path, library):
    rgb = tmp_path / "photo.png"
    from PIL import Image

    Image.new("RGB", (40, 40), (10, 200, 10)).save(rgb)
    with pytest.raises(InputError, match="no alpha channel"):
        read_rgba(rgb)
    with pytest.raises(InputError, match="no such directory"):
        process_library(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no RGBA tree images"):
        process_library(tmp_path / "empty")
    with pytest.raises(InputError):
        vary(library.paths[:1], n=2, size=SIZE, cache_dir=library.cache_dir)
    with pytest.raises(InputError):
        vary(library.paths[:2], n=0, size=SIZE, cache_dir=library.cache_dir)
    with pytest.raises(InputError):
        synthesize(library.exemplars[:2], [1.0, -0.5])
    with pytest.raises(InputError):
        VariationsConfig(weight_range=(0.8, 0.2)).validate()
    with pytest.raises(NoTreeFoundError):
        process_exemplar(np.zeros((32, 32, 4), np.uint8))
