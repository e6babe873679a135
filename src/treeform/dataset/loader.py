"""Read a generated dataset: random access to samples, augmented batches, a torch Dataset.

Examples
--------
>>> ds = SyntheticDataset("out/dataset")                                   # doctest: +SKIP
>>> for batch in ds.batches(32, augment=Augment(), seed=0):                # doctest: +SKIP
...     batch["image"].shape, batch["mask"].shape, batch["species"].shape  # (32, S, S, 3), (32, S, S), (32,)
...     [r.shape for r in batch["rbv"]]                                    # (32, 1, 1) ... (32, 16, 16)
"""

from __future__ import annotations

import tarfile
from pathlib import Path

import numpy as np

from treeform._shared.checks import check_int
from treeform._shared.errors import InputError
from treeform.dataset.storage import decode_sample, read_manifest

__all__ = ["SyntheticDataset", "TorchSynthetic", "torch_dataset"]


class SyntheticDataset:
    """The samples of a dataset directory (every finished shard), by position 0 .. len-1.

    Samples of an interrupted run that wait in ``partial/`` for the rest of their shard are
    not included: rerun the generation to finish their shard.

    Parameters
    ----------
    directory : path
        Made by :func:`treeform.dataset.generate_dataset`.

    Raises
    ------
    InputError
        No manifest, or no finished shard.
    """

    def __init__(self, directory):
        self.directory = Path(directory)
        manifest = read_manifest(self.directory)
        if manifest is None:
            raise InputError(f"{self.directory}: no manifest.json (not a generated dataset)")
        self.manifest = manifest
        self.species_names = list(manifest.get("species_names", []))
        self._entries: list[tuple[str, dict]] = []  # (shard, {suffix: (offset, size)})
        for name in sorted(manifest["shards"]):
            path = self.directory / name
            if not path.exists():
                continue
            try:
                with tarfile.open(path) as tar:
                    members: dict[str, dict] = {}
                    for info in tar:
                        key, suffix = info.name.split(".", 1)
                        members.setdefault(key, {})[suffix] = (info.offset_data, info.size)
            except (tarfile.TarError, OSError, ValueError) as exc:
                raise InputError(f"{path}: not a readable shard ({exc})") from None
            self._entries.extend((name, members[k]) for k in sorted(members))
        if not self._entries:
            raise InputError(f"{self.directory}: no finished shard yet")

    def __len__(self) -> int:
        return len(self._entries)

    def members(self, i: int, suffixes=("image.png", "mask.png", "json")) -> dict:
        """Raw bytes ``{"sample.<suffix>": bytes}`` of sample ``i`` (members it lacks are left out)."""
        name, entry = self._entries[i]
        out = {}
        with open(self.directory / name, "rb") as fh:
            for suffix in suffixes:
                if suffix in entry:
                    off, size = entry[suffix]
                    fh.seek(off)
                    out[f"sample.{suffix}"] = fh.read(size)
        return out

    def __getitem__(self, i: int) -> dict:
        """Sample ``i``: ``image`` (S, S, 3) uint8, ``mask`` (S, S) uint8, ``rbv`` (5 arrays), ``species_id``, ..."""
        if not -len(self) <= i < len(self):
            raise IndexError(i)
        return decode_sample(self.members(int(i) % len(self)))

    def batches(self, batch_size: int, *, augment=None, shuffle: bool = True, seed: int = 0,
                drop_last: bool = False):
        """Yield batches of (augmented) samples as stacked arrays.

        Parameters
        ----------
        batch_size : int
        augment : Augment, optional
            Applied to each sample with a generator derived from (seed, epoch position).
        shuffle : bool
        seed : int
            Order and augmentation; same seed -> same batches.
        drop_last : bool

        Yields
        ------
        dict
            ``image`` (B, T, T, 3) uint8, ``mask`` (B, T, T) uint8, ``rbv`` list of five
            (B, n, n) float32 arrays (levels 1–5), ``species`` (B,) int64, ``index`` (B,) int64.
        """
        check_int(batch_size, "batch_size", 1, 2**31)
        rng = np.random.default_rng(seed)
        order = rng.permutation(len(self)) if shuffle else np.arange(len(self))
        for start in range(0, len(order), batch_size):
            idx = order[start:start + batch_size]
            if drop_last and len(idx) < batch_size:
                return
            items = []
            for k, i in enumerate(idx):
                s = self[int(i)]
                if augment is not None:
                    a = augment(s["image"], s["mask"], s["rbv"], rng=np.random.default_rng([seed, start + k]))
                    s = {**s, "image": a["image"], "mask": a["mask"], "rbv": a["rbv"]}
                items.append(s)
            yield {
                "image": np.stack([s["image"] for s in items]),
                "mask": np.stack([s["mask"] for s in items]),
                "rbv": [np.stack([s["rbv"][lv] for s in items]).astype(np.float32) for lv in range(5)],
                "species": np.array([s["species_id"] for s in items], np.int64),
                "index": np.array([s["index"] for s in items], np.int64),
            }


class TorchSynthetic:
    """Map-style dataset for ``torch.utils.data.DataLoader`` (picklable: works with worker processes).

    Items are ``(image, mask, rbv, species)``: image float32 (3, T, T) in [0, 1], mask int64
    (T, T), rbv a tuple of five float32 tensors (n, n), species an int64 scalar. With
    ``augment``, item ``i`` of epoch ``e`` uses the generator ``default_rng([seed, e, i])``;
    call :meth:`set_epoch` to change it.
    """

    def __init__(self, directory, *, augment=None, seed: int = 0):
        self.base = SyntheticDataset(directory)
        self.augment = augment
        self.seed = int(seed)
        self.epoch = 0

    def set_epoch(self, epoch: int) -> None:
        self.epoch = int(epoch)

    def __len__(self) -> int:
        return len(self.base)

    def __getitem__(self, i):
        import torch

        s = self.base[i]
        image, mask, rbv = s["image"], s["mask"], s["rbv"]
        if self.augment is not None:
            a = self.augment(image, mask, rbv, rng=np.random.default_rng([self.seed, self.epoch, int(i)]))
            image, mask, rbv = a["image"], a["mask"], a["rbv"]
        return (torch.from_numpy(np.ascontiguousarray(image.transpose(2, 0, 1))).float() / 255.0,
                torch.from_numpy(mask.astype(np.int64)),
                tuple(torch.from_numpy(np.asarray(r, np.float32)) for r in rbv),
                torch.tensor(s["species_id"], dtype=torch.int64))


def torch_dataset(directory, *, augment=None, seed: int = 0) -> TorchSynthetic:
    """A :class:`TorchSynthetic` over a generated dataset, for ``torch.utils.data.DataLoader`` (needs torch).

    Raises
    ------
    InputError
        PyTorch is not installed, or ``directory`` is not a dataset.
    """
    try:
        import torch  # noqa: F401
    except ImportError:
        raise InputError("torch_dataset needs PyTorch: pip install torch") from None
    return TorchSynthetic(directory, augment=augment, seed=seed)
