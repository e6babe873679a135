"""Network definitions (torch; the optional ``train`` extra). One file per network.

Nothing here is imported by inference: the shipped weights are ONNX graphs run by
:mod:`treeform.learn.infer` with onnxruntime.
"""
