"""Export of trained networks to ONNX, the format the package ships and runs (onnxruntime).

The graph takes ``image`` (N, 3, H, W) float RGB in [0, 1] with free H and W (multiples of
8) for the segmenter (multiples of 16 for the foot detector), fixed sizes for the mask networks; metadata (``treeform_kind``,
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
    "feet": (("image",), ("heat",), {"image": {0: "n", 2: "h", 3: "w"}, "heat": {0: "n", 2: "h4", 3: "w4"}}),
}
_EXAMPLE = {"seg": (1, 3, 224, 224), "species": (1, 3, 96, 96), "rbv": (1, 3, 96, 96), "feet": (1, 3, 288, 384)}


def export_onnx(model, path, *, kind: str, metadata: dict | None = None, example_shape=None) -> Path:
    """Write ``model`` (a torch module in eval mode) as an ONNX graph at ``path`` (atomically).

    Parameters
    ----------
    model : torch.nn.Module
    path : path
    kind : {'seg', 'species', 'rbv', 'feet'}
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


def load_onnx_into(model, path, *, calibrate, new_layers: tuple[str, ...] = ()) -> None:
    """Load ONNX weights exported by :func:`export_onnx` back into ``model`` (same architecture).

    The export folds each BatchNorm into the convolution before it; here every convolution
    gets its folded weights and its BatchNorm is set so that, in eval mode, it adds the
    folded bias and nothing else, with running statistics (and a matching affine scale)
    taken from the activations of the ``calibrate`` batch, so that training mode starts
    where the exported network was. Convolutions are matched by their module path, which
    the exporter writes into each node's output name (``/stem/stem.0/stem.0.0/Conv_output_0``).

    Parameters
    ----------
    model : torch.nn.Module
    path : path
        The ONNX file.
    calibrate : torch.Tensor
        A batch of inputs, (N, 3, H, W).
    new_layers : tuple of str
        Module paths (prefixes) that the file may lack: a network grown from smaller weights
        (e.g. SegNet's ``("full", "refine")``) keeps its own initialisation there. Any other
        missing layer is an error.
    """
    import onnx
    import torch
    from onnx import numpy_helper

    from treeform._shared.errors import InputError, ModelError

    try:
        graph = onnx.load(str(path)).graph
    except Exception as e:  # noqa: BLE001 - any unreadable file
        raise ModelError(f"{path}: unreadable ONNX weights ({e})") from None
    inits = {i.name: numpy_helper.to_array(i) for i in graph.initializer}
    for node in graph.node:  # the exporter shares equal tensors (e.g. the zero biases of a fresh net) by Identity
        if node.op_type == "Identity" and node.input[0] in inits:
            inits[node.output[0]] = inits[node.input[0]]
    convs = {}
    for node in graph.node:
        if node.op_type == "Conv":
            bias = inits[node.input[2]] if len(node.input) > 2 else None
            convs[_module_path(node.output[0])] = (inits[node.input[1]], bias)
    mods = dict(model.named_modules())
    bn_bias = {}
    with torch.no_grad():
        for name, m in mods.items():
            if not isinstance(m, torch.nn.Conv2d):
                continue
            if name not in convs:
                if any(name == p or name.startswith(p + ".") for p in new_layers):
                    continue
                raise InputError(f"{path}: no weights for layer {name} (another architecture?)")
            w, b = convs.pop(name)
            if tuple(w.shape) != tuple(m.weight.shape):
                raise InputError(f"{path}: layer {name} has shape {w.shape}, the network {tuple(m.weight.shape)}")
            m.weight.copy_(torch.from_numpy(w.copy()))
            parent, _, idx = name.rpartition(".")
            bn = mods.get(f"{parent}.{int(idx) + 1}") if idx.isdigit() else None
            bias = (torch.from_numpy(b.copy()) if b is not None else torch.zeros(w.shape[0])).to(m.weight.device)
            if isinstance(bn, torch.nn.BatchNorm2d):
                bn.running_mean.zero_()
                bn.running_var.fill_(1.0 - bn.eps)
                bn.weight.fill_(1.0)
                bn.bias.copy_(bias)
                bn_bias[bn] = bias
            elif m.bias is not None:
                m.bias.copy_(bias)
        # running statistics: each BatchNorm's input on the calibration batch (the network is exact now)
        stats, hooks = {}, []
        for bn in bn_bias:
            def hook(mod, inp, _out):
                z = inp[0]
                stats[mod] = (z.mean(dim=(0, 2, 3)), z.var(dim=(0, 2, 3), unbiased=False))
            hooks.append(bn.register_forward_hook(hook))
        was = model.training
        model.eval()
        model(calibrate)
        for h in hooks:
            h.remove()
        for bn, bias in bn_bias.items():
            mu, var = stats[bn]
            bn.running_mean.copy_(mu)
            bn.running_var.copy_(var)
            bn.weight.copy_(torch.sqrt(var + bn.eps))
            bn.bias.copy_(mu + bias)
        model.train(was)


def _module_path(output_name: str) -> str:
    """``stem.1.body.0.0`` from the exporter's scope ``/stem/stem.1/body/body.0/body.0.0/Conv_output_0``
    (each scope names its module relative to the one before when it extends it).

    >>> _module_path("/stem/stem.1/body/body.0/body.0.0/Conv_output_0")
    'stem.1.body.0.0'
    >>> _module_path("/head/Conv_output_0")
    'head'
    """
    parts, prev = [], None
    for seg in output_name.strip("/").split("/")[:-1]:
        parts.append(seg[len(prev) + 1:] if prev is not None and seg.startswith(prev + ".") else seg)
        prev = seg
    return ".".join(parts)
