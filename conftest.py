"""Repository-level pytest set-up: modules that need the optional ``train`` extra (torch, onnx)
are not imported for doctests when it is not installed."""

import importlib.util

collect_ignore_glob = []
if importlib.util.find_spec("torch") is None or importlib.util.find_spec("onnx") is None:
    collect_ignore_glob += ["src/treeform/learn/nets/*.py", "src/treeform/learn/train*.py",
                            "src/treeform/learn/export.py"]
