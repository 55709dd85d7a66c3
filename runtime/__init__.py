"""The torch-free deployment runtime: every task end to end from the ONNX graphs of a deployment bundle
(``export/`` writes them), with numpy, onnxruntime and OpenCV only.

``python -m runtime.<task> --bundle DIR ...`` per task: ``triangulation``, ``tracking``, ``horizon``, ``localize``
(the horizon bundle on a filter bank), ``vos``, ``davos`` (``runtime.segmentation`` picks the VOS tracker of a
bundle). Modules import only the standard library, numpy, onnxruntime, OpenCV and the torch-free modules of
``core`` (``tests/test_layers.py`` checks it), so ``runtime/`` and ``core/`` copied to a board with
``pip install '.[runtime]'`` run without torch (docs/deployment.md).
"""
