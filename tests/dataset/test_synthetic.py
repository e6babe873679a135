"""One synthetic sample: exact labels, reproducibility, RBV and options."""

from __future__ import annotations

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.dataset import LABELS, SampleOptions, make_sample
from treeform.dataset.storage import encode_sample
from treeform.growth.species import SPECIES
from treeform.render import Renderer

OPTS = SampleOptions(size=64, lod="low")


@pytest.fixture(scope="module")
def samples(gl):
    return [make_sample(7, i, OPTS) for i in range(3)]


def test_sample_arrays(samples):
    for s in samples:
        assert s.image.shape == (64, 64, 3) and s.image.dtype == np.uint8
        assert s.mask.shape == (64, 64) and set(np.unique(s.mask)) <= set(LABELS.values())
        assert (s.mask == LABELS["foliage"]).any()
        assert [r.shape for r in s.rbv] == [(1, 1), (2, 2), (4, 4), (8, 8), (16, 16)]
        for coarse, fine in zip(s.rbv[:-1], s.rbv[1:]):  # a coarse cell bounds its four children
            n = coarse.shape[0]
            assert np.allclose(coarse, fine.reshape(n, 2, n, 2).max(axis=(1, 3)))
        assert s.rbv_height > 1 and s.rbv_radius > 0
        assert SPECIES[s.species_id] == s.species and s.params["age"] >= 4
        assert s.skeleton.n_nodes > 10 and 1 <= s.meta["lighting"]["lights"] <= 8


def test_mask_agrees_with_a_fresh_background_free_render(samples):
    """Re-render each scene alone, from scratch, at the supersampled size: same coverage as the mask."""
    for s in samples:
        f = OPTS.supersample
        from dataclasses import replace

        cam = replace(s.camera, width=64 * f, height=64 * f)
        res = Renderer(cam, samples=1, lighting=s.lighting).render(s.mesh)
        cover = res.mask.reshape(64, f, 64, f).sum(axis=(1, 3))
        alpha = 2 * cover >= f * f
        tree = s.mask > 0
        iou = (alpha & tree).sum() / (alpha | tree).sum()
        assert iou >= 0.99, iou
        assert ((s.rgba[..., 3] >= 128) == tree).all()  # the tree's own alpha in the sample


def test_branches_are_labelled_where_bark_is_seen(samples):
    s = samples[0]
    f = OPTS.supersample
    from dataclasses import replace

    res = Renderer(replace(s.camera, width=64 * f, height=64 * f), samples=1).render(s.mesh)
    bark = [k for k, p in enumerate(s.mesh.parts) if p.name == "bark"][0]
    wood = (res.part == bark).reshape(64, f, 64, f).sum(axis=(1, 3))
    assert (s.mask[wood == f * f] == LABELS["branch"]).all()


def test_same_seed_and_index_give_identical_bytes(samples):
    again = make_sample(7, 1, OPTS)
    a, b = encode_sample(samples[1]), encode_sample(again)
    assert a.keys() == b.keys() and all(a[k] == b[k] for k in a)
    other = make_sample(8, 1, OPTS)
    assert not (other.image == samples[1].image).all()


def test_species_option_and_errors(gl):
    s = make_sample(0, 0, SampleOptions(size=48, species=("pine",), lod="low", supersample=1))
    assert s.species == "pine" and s.species_id == SPECIES.index("pine")
    with pytest.raises(InputError, match="species"):
        SampleOptions(species=("palm",)).validate()
    with pytest.raises(InputError, match="size"):
        SampleOptions(size=8).validate()
    with pytest.raises(InputError, match="supersample"):
        SampleOptions(supersample=9).validate()


def test_mesh_is_stored_on_request(gl, tmp_path):
    from treeform.io import read_glb_counts

    s = make_sample(7, 0, SampleOptions(size=48, lod="low", supersample=1, mesh=True))
    members = encode_sample(s)
    glb = [v for k, v in members.items() if k.endswith(".glb")]
    assert len(glb) == 1
    (tmp_path / "t.glb").write_bytes(glb[0])
    assert read_glb_counts(tmp_path / "t.glb")[1] == s.mesh.n_triangles
    assert not any(k.endswith(".glb") for k in encode_sample(make_sample(7, 0, SampleOptions(size=48, lod="low",
                                                                                            supersample=1))))


def test_bare_samples_are_winter_trees_and_leave_the_others_alone(gl, samples):
    """--bare: a share of the samples drawn leafless (every tree pixel wood); the others byte-identical."""
    bare = [make_sample(7, i, SampleOptions(size=64, lod="low", bare=0.5)) for i in range(6)]
    kinds = [bool(s.meta.get("bare")) for s in bare]
    assert any(kinds) and not all(kinds)
    for i, s in enumerate(bare):
        if s.meta.get("bare"):
            assert not (s.mask == LABELS["foliage"]).any() and (s.mask == LABELS["branch"]).any()
            assert s.meta["leaves"] == 0 and {p.name for p in s.mesh.parts} == {"bark"}
            # the same tree as its leafy self: species, growth and RBV (the skeleton's) unchanged
            leafy = samples[i] if i < 3 else make_sample(7, i, OPTS)
            assert s.species == leafy.species and s.skeleton.n_nodes == leafy.skeleton.n_nodes
            assert all(np.array_equal(a, b) for a, b in zip(s.rbv, leafy.rbv))
        else:
            leafy = samples[i] if i < 3 else make_sample(7, i, OPTS)
            a, b = encode_sample(s), encode_sample(leafy)
            assert a.keys() == b.keys() and all(a[k] == b[k] for k in a)
    everyone = make_sample(7, 0, SampleOptions(size=64, lod="low", bare=1.0))
    assert everyone.meta["bare"] and not (everyone.mask == LABELS["foliage"]).any()
    with pytest.raises(InputError, match="bare"):
        SampleOptions(bare=1.5).validate()
