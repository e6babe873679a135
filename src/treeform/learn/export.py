"""Export of trained networks to ONNX, the format the package ships and runs (onnxruntime).

The graph takes ``image`` (N, 3, H, W) float RGB in [0, 1] with free H and W (multiples of
8) for the segmenter, fixed sizes for the mask networks; metadata (``treeform_kind``,
training settings) travels in the model's ``metadata_props``.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["export_onnx"]

_IO = {
    "seg": (("image",), ("logits",), {"image": {0: "n", 2: "h", 3: "w"}, "logits": {0: "n", 2: "h", 3: "w"}}),
    "species": (("mask",), ("logits",), {"mask": {0: "n"}, "logits": {0: "n"}}),
    "rbv": (("mask",), ("rbv",), {"mask": {0: "n"}, "rbv": {0: "n"}}),
}
_EXAMPLE = {"seg": (1, 3, 224, 224), "species": (1, 3, 96, 96), "rbv": (1, 3, 96, 96)}


def export_onnx(model, path, *, kind: str, metadata: dict | None = None, example_shape=None) -> Path:
    """Write ``model`` (a torch module in eval mode) as an ONNX graph at ``path`` (atomically).

    Parameters
    ----------
    model : torch.nn.Module
    path : path
    kind : {'seg', 'species', 'rbv'}
    metadata : dict, optional
        Extra ``metadata_props`` (values stored as strings).
    example_shape : tuple, optional
        Input shape for tracing (default per kind).
    """
    import onnx
    import torch

    names_in, names_out, dyn = _IO[kind]
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    model = model.eval()
    x = torch.zeros(example_shape or _EXAMPLE[kind])
    with torch.no_grad():
        torch.onnx.export(model, (x,), str(tmp), input_names=list(names_in), output_names=list(names_out),
                          dynamic_axes=dyn, opset_version=17, dynamo=False)
    m = onnx.load(str(tmp))
    meta = {"treeform_kind": kind, **{k: str(v) for k, v in (metadata or {}).items()}}
    for k, v in meta.items():
        p = m.metadata_props.add()
        p.key, p.value = k, str(v)
    onnx.save(m, str(tmp))
    os.replace(tmp, path)
    return path
