"""Image-based tree variations (seed 000): exemplars, synthesis, colour and histogram transfer."""

from pathlib import Path

import numpy as np
import pytest

from treeform._shared.errors import InputError, NoTreeFoundError
from treeform.contour import fill_contour, longest_exterior_contour, pin_points
from treeform.methods.variations import (
    VariationsConfig,
    classify_form,
    form_descriptor,
    match_histograms,
    morph,
    normalize_rgba,
    process_exemplar,
    read_rgba,
    season_reference,
    season_transfer,
    synthesize,
    vary,
)
from treeform.methods.variations.season import crown_trunk_labels, mean_hue, quantile_map
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


# --------------------------------------------------------------------------- season transfer (§5.3)

PHOTOS = ROOT.parent / "shared" / "data" / "photos"
AUTUMN = ["Acer_saccharinum_2.jpg", "Morus_rubra_1.jpg", "Asimina_triloba_1.jpg"]  # yellow autumn crowns


@pytest.fixture(scope="module")
def references():
    if not PHOTOS.is_dir():
        pytest.skip("../shared/data/photos is not available")
    from treeform.io import read_photo

    return {name: season_reference(read_photo(PHOTOS / name).image, seed=0)
            for name in AUTUMN + ["Acer_rubrum_2.jpg"]}


def _hue(rgba, where):
    return mean_hue(rgba[where & (rgba[..., 3] > 0)][:, :3])[0]


def _pixel_hues(px):
    from treeform.methods.variations.season import _to_space

    lab = _to_space(np.asarray(px, np.uint8), "lab")
    coloured = np.hypot(lab[:, 1], lab[:, 2]) >= 4  # the hue of a grey pixel is noise
    return np.degrees(np.arctan2(lab[coloured, 2], lab[coloured, 1]))


@pytest.mark.parametrize("photo", AUTUMN)
def test_season_transfer_gives_the_crown_the_photo_hue_and_keeps_the_trunk_bark(library, references, photo):
    ex = _by_name(library, "cesium_tree_billboard.png")  # a green broadleaf
    ref = references[photo]
    out = season_transfer(ex.rgba, ex.labels, ref)
    lab = crown_trunk_labels(ex.rgba, ex.labels)
    crown, trunk = lab == 1, lab == 2
    photo_hue = mean_hue(ref.crown)[0]
    before, after = _hue(ex.rgba, crown), _hue(out, crown)
    assert before - photo_hue > 25  # green (127 deg) against yellow (89-98 deg)
    assert abs(after - photo_hue) < 4, (before, after, photo_hue)
    assert np.array_equal(out[..., 3], ex.rgba[..., 3])
    assert np.array_equal(out[ex.rgba[..., 3] == 0], ex.rgba[ex.rgba[..., 3] == 0])
    if ref.has_trunk:  # the trunk takes the photo's bark colours, inside their hue range
        lo, hi = np.percentile(_pixel_hues(ref.trunk), [10, 90])
        assert lo <= _hue(out, trunk) <= hi and 20 < _hue(out, trunk) < 110, (lo, _hue(out, trunk), hi)
    else:  # no trunk visible in the photo: the exemplar's own bark, untouched
        assert np.array_equal(out[trunk], ex.rgba[trunk]) and 20 < _hue(out, trunk) < 120
    # the cause of the issue: the paper's transfer against the whole photo (sky, lawn)
    # turns the trunk purple and the crown towards cyan
    whole = match_histograms(ex.rgba, read_rgba(PHOTOS / photo, require_alpha=False))
    assert _hue(whole, trunk) < 0 and abs(_hue(whole, crown) - photo_hue) > abs(after - photo_hue) + 10


def test_season_reference_takes_the_tree_and_its_trunk_only(references):
    from treeform.io import read_photo

    image = read_photo(PHOTOS / "Acer_rubrum_2.jpg").image  # a maple under a blue sky, trunk visible
    ref = references["Acer_rubrum_2.jpg"]

    def blue(px):
        from treeform.methods.variations.season import _to_space

        return float((_to_space(px, "lab")[:, 2] < -8).mean())

    assert blue(image.reshape(-1, 3)) > 0.2 and blue(ref.crown) < 0.02  # the sky is left out
    # (the network's trunk is the bark alone, 2.9 % of the crown's pixels; the colour rules' was 7 %, planters
    # at its foot included)
    assert ref.has_trunk and len(ref.trunk) > 0.02 * len(ref.crown)
    ys = np.nonzero(ref.labels == 2)[0]
    rows = np.nonzero(ref.labels.any(1))[0]
    assert np.median(ys) > rows.min() + 0.7 * (rows.max() - rows.min())  # at the foot of the tree
    assert 60 < mean_hue(ref.trunk)[0] < 110 and mean_hue(ref.trunk)[1] < 15  # grey-brown bark
    # the autumn trees' trunks are hidden by hedges and leaves; the "wood" at their feet
    # is a grass plume off to the side (silver maple) and the road (mulberry)
    assert not any(references[p].has_trunk for p in AUTUMN)
    again = season_reference(image, seed=0)
    assert np.array_equal(again.labels, ref.labels) and np.array_equal(again.crown, ref.crown)


def test_season_transfer_in_lab_keeps_hues_that_rgb_turns_pink(library, references):
    """Per-channel RGB matching moves each channel's rank on its own: greyish stems and
    shaded leaves come out pink or purple; L*a*b* keeps lightness apart from colour."""
    from treeform.methods.variations.season import _to_space

    ex = _by_name(library, "cesium_tree_billboard.png")
    lab = crown_trunk_labels(ex.rgba, ex.labels)
    crown = (lab == 1) & (ex.rgba[..., 3] >= 128)

    def off_hue(rgba):  # crown pixels neither red, orange, yellow nor green
        c = _to_space(rgba[crown][:, :3], "lab")
        h = np.degrees(np.arctan2(c[:, 2], c[:, 1]))
        return float((((h < 20) | (h > 150)) & (np.hypot(c[:, 1], c[:, 2]) > 8)).mean())

    for photo in ("Acer_rubrum_2.jpg", "Morus_rubra_1.jpg"):
        ref = references[photo]
        in_lab = off_hue(season_transfer(ex.rgba, ex.labels, ref))
        in_rgb = off_hue(season_transfer(ex.rgba, ex.labels, ref, space="rgb"))
        assert in_lab < 0.06 and in_rgb > 2.5 * in_lab, (photo, in_lab, in_rgb)
    ref = references["Acer_rubrum_2.jpg"]  # a visible trunk: its bark goes onto the trunk
    # compared by the mean a*b* (chromatic distance), not the hue angle: grey bark has a chroma of about
    # 1, where a hue angle swings by degrees for a tenth of a unit (0.3 apart when written; the crown's
    # colours stand 14 apart from the bark's)
    out = season_transfer(ex.rgba, ex.labels, ref)
    got = _to_space(out[(lab == 2) & (out[..., 3] > 0)][:, :3], "lab").mean(0)
    want = _to_space(ref.trunk, "lab").mean(0)
    assert np.hypot(*(got[1:] - want[1:])) < 2.0


def test_low_leaves_below_the_crown_baseline_take_crown_colours(library):
    ex = _by_name(library, "cesium_tree_billboard.png")  # leafy low branches below the baseline
    lab = crown_trunk_labels(ex.rgba, ex.labels)
    moved = (ex.labels == 2) & (lab == 1)
    assert 0.1 < moved.sum() / (ex.labels == 2).sum() < 0.5
    assert mean_hue(ex.rgba[moved][:, :3])[0] > 120  # green leaves
    assert mean_hue(ex.rgba[lab == 2][:, :3])[1] < 20  # what is left is grey bark
    palm = _by_name(library, "tropical-alt_row3_col5.png")  # a trunk coloured much like its fronds
    kept = (crown_trunk_labels(palm.rgba, palm.labels) == 2).sum() / (palm.labels == 2).sum()
    assert kept > 0.85


def test_quantile_map_and_season_transfer_edge_cases(library):
    rng = np.random.default_rng(4)
    src, ref = rng.normal(0, 1, 5000), rng.gamma(2.0, 3.0, 3000)
    got = quantile_map(src, ref)
    qs = np.linspace(0.02, 0.98, 25)
    assert np.abs(np.quantile(got, qs) - np.quantile(ref, qs)).max() < 0.15
    assert np.all(np.diff(got[np.argsort(src)]) >= 0)  # monotonic: the order of values is kept
    ex = _by_name(library, "savanna-trees_row3_col0.png")
    # an RGBA tree as the reference: its alpha is the mask, no segmentation
    cut = _by_name(library, "coniferous_row3_col0.png").rgba
    ref = season_reference(cut)
    assert np.array_equal(ref.labels > 0, cut[..., 3] >= 128)  # sky gaps are not looked for
    whole = season_transfer(ex.rgba, None, ref)  # no labels: all one crown
    crown = season_transfer(ex.rgba, ex.labels, ref)
    assert not np.array_equal(whole, crown) and np.array_equal(whole[..., 3], ex.rgba[..., 3])
    empty = np.zeros((32, 32, 4), np.uint8)
    assert np.array_equal(season_transfer(empty, None, ref), empty)
    for kwargs in ({"space": "hsv"}, {"threshold": 2.0}):
        with pytest.raises(InputError):
            season_transfer(ex.rgba, ex.labels, ref, **kwargs)
    with pytest.raises(InputError, match="labels"):
        season_transfer(ex.rgba, ex.labels[:10], ref)
    with pytest.raises(InputError, match="reference"):
        season_transfer(ex.rgba, ex.labels, np.zeros((8, 8, 3), np.uint8))
    with pytest.raises(InputError, match="min_trunk"):
        season_reference(ex.rgba, min_trunk=3)
    with pytest.raises(NoTreeFoundError):
        season_reference(np.zeros((40, 40, 4), np.uint8) + np.array([0, 0, 0, 1], np.uint8))
    with pytest.raises(InputError):
        VariationsConfig(season_space="hsv").validate()


def test_synthesised_trees_carry_crown_and_trunk_labels(library):
    a = _by_name(library, "savanna-trees_row3_col3.png")
    b = _by_name(library, "cerrado-trees_row3_col3.png")
    end = synthesize([a, b], [1.0, 0.0], colour_weights=[1.0, 0.0])  # the identity warp of a
    inside = end.labels > 0
    t_a, t_s = (a.labels == 2) & inside, end.labels == 2
    assert (t_a & t_s).sum() / (t_a | t_s).sum() > 0.9
    assert np.array_equal(end.labels > 0, end.rgba[..., 3] > 0)
    mid = synthesize([a, b], [0.5, 0.5])
    rows = np.nonzero(mid.labels == 2)[0]
    assert rows.size and np.median(rows) > np.median(np.nonzero(mid.labels == 1)[0])  # trunk below crown


# --------------------------------------------------------------------------- growth forms

def _form_truth(name):
    """Ground truth for this test only: the FlightGear atlas names, checked by eye."""
    if name == "tropical-alt_row3_col1.png":
        return "broadleaf"  # a broadleaf tree in the tropical atlas
    if name in ("caatinga-trees_row3_col1.png", "caatinga-trees_row3_col3.png"):
        return None  # cacti: none of the three forms
    if name.startswith("coniferous"):
        return "conifer"
    if name.startswith("tropical"):
        return "palm"  # coconut palms, a fan palm, a banana plant
    return "broadleaf"  # caatinga, cerrado, savanna atlases and the cesium tree


def test_growth_forms_of_the_shared_billboards(library):
    pairs = [(_form_truth(n), e.form) for n, e in zip(library.names, library.exemplars) if _form_truth(n)]
    assert len(pairs) == 35
    right = sum(t == f for t, f in pairs)
    assert right >= 30, pairs  # 31 of 35 when written (module docstring of treeform.contour.form)
    assert all(f == "broadleaf" for t, f in pairs if t == "broadleaf")  # no broadleaf taken for a palm
    assert _by_name(library, "cesium_tree_billboard.png").form == "broadleaf"
    for col in (3, 5, 6, 7):  # coconut palms
        assert _by_name(library, f"tropical-alt_row3_col{col}.png").form == "palm"
    for col in (0, 2, 3, 5, 6, 7):
        assert _by_name(library, f"coniferous_row3_col{col}.png").form == "conifer"
    # the form comes from the silhouette, not the name; the same at another size
    d = form_descriptor(read_rgba(BILLBOARDS / "tropical-alt_row3_col5.png"))
    assert d.form == "palm" and d.radiality > 0.5 and d.stem > 0.3
    assert classify_form(_by_name(library, "tropical-alt_row3_col5.png").rgba[::2, ::2].copy()) == "palm"
    with pytest.raises(InputError):
        classify_form(np.zeros((20, 20, 3), np.uint8))


def test_variations_combine_trees_of_one_form_unless_asked(library):
    t = library.paths[library.names.index("cesium_tree_billboard.png")]
    same = vary(library, n=6, from_tree=t, seed=1, size=SIZE)
    anyf = vary(library, n=6, from_tree=t, seed=1, size=SIZE, any_form=True)
    assert all(r["forms"] == ["broadleaf", "broadleaf"] for r in same.records)
    # the cesium tree's nearest contours include palms: what the issue saw
    assert any("palm" in r["forms"] for r in anyf.records)
    conifer = library.paths[library.names.index("coniferous_row3_col2.png")]
    res = vary(library, n=4, from_tree=conifer, seed=2, size=SIZE)
    assert all(r["forms"] == ["conifer", "conifer"] for r in res.records)
    with pytest.raises(InputError, match="any_form"):
        VariationsConfig(any_form="yes").validate()


def test_vary_with_a_season_photo_is_reproducible(library, tmp_path):
    if not PHOTOS.is_dir():
        pytest.skip("../shared/data/photos is not available")
    sub = [library.paths[library.names.index(n)] for n in ("cesium_tree_billboard.png", "cerrado-trees_row3_col0.png",
                                                           "savanna-trees_row3_col3.png")]
    cfg = VariationsConfig(size=SIZE, tile=64)
    kw = dict(n=2, season=PHOTOS / "Morus_rubra_1.jpg", seed=3, config=cfg, cache_dir=library.cache_dir)
    r1 = vary(sub, out=tmp_path / "a", **kw)
    r2 = vary(sub, out=tmp_path / "b", **kw)
    for name in ("variation_000.png", "variation_001.png", "config.json"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    assert r2.records == r1.records
    plain = vary(sub, **{**kw, "season": None})
    assert plain.records == r1.records  # the season changes colours only
    for img, base in zip(r1.images, plain.images):
        assert np.array_equal(img[..., 3], base[..., 3]) and not np.array_equal(img, base)
    with pytest.raises(NoTreeFoundError, match="season"):
        vary(sub, **{**kw, "season": np.full((64, 64, 3), 128, np.uint8)})
