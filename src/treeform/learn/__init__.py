"""Learned perception (seed 003 §4.2): network definitions and training (torch, optional), ONNX
export, and inference with onnxruntime.

- :mod:`treeform.learn.nets` — the networks (torch);
- :mod:`treeform.learn.train` — ``treeform train``: seeded, checkpointed, resumable;
- :mod:`treeform.learn.export` — torch -> ONNX;
- :mod:`treeform.learn.infer` — onnxruntime sessions over the shipped ``weights/*.onnx``;
- :mod:`treeform.learn.data` — the randomised scenes the networks train and are tested on.

Importing this package imports neither torch nor onnxruntime.
"""
