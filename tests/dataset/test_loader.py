"""Reading a generated dataset: random access, augmented batches, contact sheet, torch wrapper."""

from __future__ import annotations

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.dataset import Augment, SyntheticDataset, generate_dataset, show_dataset


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory, gl):
    out = tmp_path_factory.mktemp("loader") / "ds"
    generate_dataset(out, n=6, workers=1, seed=2, shard_size=4, size=48, lod="low", supersample=1)
    return out


def test_random_access(data_dir):
    ds = SyntheticDataset(data_dir)
    assert len(ds) == 6
    s = ds[4]
    assert s["index"] == 4 and s["image"].shape == (48, 48, 3) and s["mask"].shape == (48, 48)
    assert [r.shape for r in s["rbv"]] == [(1, 1), (2, 2), (4, 4), (8, 8), (16, 16)]
    assert ds.species_names[s["species_id"]] == s["species"]
    assert (ds[-2]["image"] == s["image"]).all()
    with pytest.raises(IndexError):
        ds[6]


def test_batches_are_stacked_augmented_and_reproducible(data_dir):
    ds = SyntheticDataset(data_dir)
    aug = Augment(crop_min=32, out_size=40)
    batches = list(ds.batches(4, augment=aug, seed=9))
    assert [len(b["index"]) for b in batches] == [4, 2]
    b = batches[0]
    assert b["image"].shape == (4, 40, 40, 3) and b["mask"].shape == (4, 40, 40)
    assert [r.shape for r in b["rbv"]] == [(4, 1, 1), (4, 2, 2), (4, 4, 4), (4, 8, 8), (4, 16, 16)]
    assert b["species"].dtype == np.int64
    again = next(ds.batches(4, augment=aug, seed=9))
    assert (again["image"] == b["image"]).all() and (again["index"] == b["index"]).all()
    assert sorted(np.concatenate([x["index"] for x in batches]).tolist()) == list(range(6))
    assert [len(x["index"]) for x in ds.batches(4, drop_last=True)] == [4]


def test_contact_sheet(data_dir, tmp_path):
    from PIL import Image

    path = show_dataset(data_dir, n=4, out=tmp_path / "sheet.png", tile=64)
    sheet = np.asarray(Image.open(path))
    assert sheet.shape[0] > 64 and sheet.shape[1] > 4 * 2 * 64
    assert (sheet == (40, 70, 230)).all(axis=-1).any() or (sheet == (40, 170, 60)).all(axis=-1).any()


def test_not_a_dataset(tmp_path):
    with pytest.raises(InputError, match="manifest"):
        SyntheticDataset(tmp_path)


def test_torch_dataset(data_dir):
    torch = pytest.importorskip("torch")
    from treeform.dataset import torch_dataset

    tds = torch_dataset(data_dir, augment=Augment(crop_min=32, out_size=32))
    image, mask, rbv, species = tds[0]
    assert image.shape == (3, 32, 32) and image.dtype == torch.float32 and mask.dtype == torch.int64
    assert len(rbv) == 5 and species.ndim == 0
    loader = torch.utils.data.DataLoader(tds, batch_size=3, num_workers=2, multiprocessing_context="spawn")
    images, masks, rbvs, species = next(iter(loader))
    assert images.shape == (3, 3, 32, 32) and rbvs[4].shape == (3, 16, 16) and species.shape == (3,)
