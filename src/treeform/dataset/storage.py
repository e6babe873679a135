"""Sharded storage of synthetic samples: deterministic tar shards + a JSON manifest.

Layout of a dataset directory::

    manifest.json        seed, options, shard size, the finished shards (name, first index,
                         count, samples, bytes, SHA-256), species names
    failures.json        samples that failed twice: index, error, attempts
    shard-00000.tar      samples 0 .. shard_size-1, WebDataset-style members per sample:
        00000000.image.png     RGB image (S, S, 3)
        00000000.mask.png      labels (S, S): 0 background, 1 foliage, 2 branch
        00000000.rgba.png      the tree alone (S, S, 4), alpha = pixel coverage (for re-compositing
                               over other scenes when training perception networks)
        00000000.json          species, species_id, rbv (levels 1-5), rbv_height, rbv_radius,
                               params, meta (camera, lights, materials, background)
        00000000.skeleton.json the branch graph (TreeSkeleton JSON)
        00000000.glb           the mesh (only with ``mesh=True``)
    partial/             while a run is under way: each finished sample of a shard not yet
                         written, as its own small tar of the same members (``00000123.tar``),
                         written atomically the moment the sample arrives. A rerun keeps them
                         (a kill loses only the samples being computed), builds each shard from
                         them once all its samples are in, then deletes them.

Tar headers carry no time, owner or permissions that vary, and PNGs are written with fixed
settings, so a shard's bytes depend only on its samples: regenerating a sample from
(seed, index) gives byte-identical members, and a shard built from kept partial samples is
byte-identical to one written by an uninterrupted run.
"""

from __future__ import annotations

import io
import json
import os
import tarfile
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError, OutputError

__all__ = ["MEMBER_SUFFIXES", "PARTIAL", "decode_sample", "encode_sample", "partial_indices", "partial_path",
           "read_manifest", "read_partial", "read_shard", "shard_name", "write_manifest", "write_partial",
           "write_shard", "FORMAT"]

FORMAT = "treeform-synthetic-trees/1"
MEMBER_SUFFIXES = ("image.png", "mask.png", "rgba.png", "json", "skeleton.json", "glb")
PARTIAL = "partial"
"""Folder (in a dataset directory) of the finished samples of shards not yet written."""


def shard_name(k: int) -> str:
    """File name of shard ``k``: ``shard-00000.tar``."""
    return f"shard-{int(k):05d}.tar"


def _png(array: np.ndarray) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(array)).save(buf, format="PNG", compress_level=1, optimize=False)
    return buf.getvalue()


def _json(obj) -> bytes:
    return json.dumps(obj, separators=(",", ":"), sort_keys=True).encode()


def encode_sample(sample) -> dict:
    """A :class:`~treeform.dataset.synthetic.Sample` as tar members ``{name: bytes}`` (deterministic)."""
    key = f"{sample.index:08d}"
    record = {"index": sample.index, "species": sample.species, "species_id": sample.species_id,
              "rbv": [np.round(r, 6).tolist() for r in sample.rbv], "rbv_height": round(sample.rbv_height, 6),
              "rbv_radius": round(sample.rbv_radius, 6), "params": sample.params, "meta": sample.meta}
    out = {f"{key}.image.png": _png(sample.image), f"{key}.mask.png": _png(sample.mask),
           f"{key}.rgba.png": _png(sample.rgba),
           f"{key}.json": _json(record), f"{key}.skeleton.json": sample.skeleton.to_json().encode()}
    if sample.store_mesh:
        import tempfile

        from treeform.io import write_glb

        with tempfile.TemporaryDirectory() as tmp:
            path = write_glb(sample.mesh, Path(tmp) / "tree.glb")
            out[f"{key}.glb"] = path.read_bytes()
    return out


def decode_sample(members: dict) -> dict:
    """Tar members of one sample -> ``{"image", "mask", "rbv", "species_id", "species", "record", ...}``.

    ``rbv`` is a list of the five level arrays; ``skeleton`` a TreeSkeleton when present.
    """
    from PIL import Image

    out = {}
    for name, data in members.items():
        suffix = name.split(".", 1)[1]
        if suffix == "image.png":
            out["image"] = np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))
        elif suffix == "mask.png":
            out["mask"] = np.asarray(Image.open(io.BytesIO(data)))
        elif suffix == "rgba.png":
            out["rgba"] = np.asarray(Image.open(io.BytesIO(data)).convert("RGBA"))
        elif suffix == "json":
            rec = json.loads(data)
            out["record"] = rec
            out["rbv"] = [np.asarray(r, np.float32) for r in rec["rbv"]]
            out["species_id"] = int(rec["species_id"])
            out["species"] = rec["species"]
            out["index"] = int(rec["index"])
        elif suffix == "skeleton.json":
            from treeform.structures import TreeSkeleton

            out["skeleton"] = TreeSkeleton.from_dict(json.loads(data))
        elif suffix == "glb":
            out["glb"] = data
    return out


def write_shard(path, samples) -> dict:
    """Write encoded samples (dicts of members, in index order; any iterable) to a tar atomically; its facts.

    Returns
    -------
    dict
        ``{"bytes": int, "sha256": str}``.
    """
    import hashlib

    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    try:
        with open(tmp, "wb") as fh:
            with tarfile.open(fileobj=fh, mode="w", format=tarfile.USTAR_FORMAT) as tar:
                for members in samples:
                    for name in sorted(members):
                        data = members[name]
                        info = tarfile.TarInfo(name)
                        info.size = len(data)
                        info.mtime = 0
                        info.mode = 0o644
                        info.uid = info.gid = 0
                        info.uname = info.gname = ""
                        tar.addfile(info, io.BytesIO(data))
        digest = hashlib.sha256(tmp.read_bytes()).hexdigest()
        size = tmp.stat().st_size
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise OutputError(f"{path}: cannot write the shard ({exc.strerror or exc})") from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return {"bytes": size, "sha256": digest}


def partial_path(directory, index: int) -> Path:
    """Where sample ``index`` waits for its shard: ``DIR/partial/00000123.tar``."""
    return Path(directory) / PARTIAL / f"{int(index):08d}.tar"


def write_partial(directory, index: int, members: dict) -> Path:
    """Store one finished sample at once (atomically), until its shard is written."""
    path = partial_path(directory, index)
    try:
        path.parent.mkdir(exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{path.parent}: cannot create ({exc.strerror or exc})") from None
    write_shard(path, [members])
    return path


def read_partial(directory, index: int) -> dict:
    """The members of a stored partial sample."""
    samples = read_shard(partial_path(directory, index))
    if len(samples) != 1:
        raise InputError(f"{partial_path(directory, index)}: expected one sample, found {len(samples)}")
    return samples[0]


def partial_indices(directory, *, clean: bool = False) -> set[int]:
    """Indices of the partial samples stored in ``DIR/partial`` (complete files only).

    With ``clean`` (a run starting, when no other run writes there), leftovers of a killed
    write (``*.tmp``) and files that cannot be whole tars (size not a positive multiple of
    512 bytes) are deleted: those samples are simply made again. Without it nothing is
    touched, so a run in progress can be watched safely.
    """
    folder = Path(directory) / PARTIAL
    if not folder.is_dir():
        return set()
    found = set()
    for p in folder.iterdir():
        stem = p.name[:-4] if p.name.endswith(".tar") else None
        try:
            size = p.stat().st_size
        except OSError:
            continue
        if stem is not None and stem.isdigit() and len(stem) == 8 and size >= 1024 and size % 512 == 0:
            found.add(int(stem))
        elif clean and (p.name.endswith(".tmp") or stem is not None):
            p.unlink(missing_ok=True)
    return found


def read_shard(path) -> list[dict]:
    """The samples of a shard as lists of members: ``[{name: bytes}, ...]`` in file order."""
    samples: dict[str, dict] = {}
    try:
        with tarfile.open(path, mode="r") as tar:
            for info in tar:
                if not info.isfile():
                    continue
                key = info.name.split(".", 1)[0]
                samples.setdefault(key, {})[info.name] = tar.extractfile(info).read()
    except FileNotFoundError:
        raise InputError(f"{path}: no such shard") from None
    except (tarfile.TarError, OSError) as exc:
        raise InputError(f"{path}: not a readable shard ({exc})") from None
    return list(samples.values())


def read_manifest(directory) -> dict | None:
    """The manifest of a dataset directory, or None when there is none yet."""
    path = Path(directory) / "manifest.json"
    if not path.exists():
        return None
    try:
        m = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not a readable manifest ({exc})") from None
    if not isinstance(m, dict) or m.get("format") != FORMAT:
        raise InputError(f"{path}: not a treeform synthetic dataset manifest")
    return m


def write_manifest(directory, manifest: dict, name: str = "manifest.json") -> Path:
    """Write ``manifest`` (or another JSON file of the dataset) atomically."""
    path = Path(directory) / name
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(json.dumps(manifest, indent=1, sort_keys=True))
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise OutputError(f"{path}: cannot write ({exc.strerror or exc})") from None
    return path
