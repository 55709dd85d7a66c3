"""The bottom layer every other package builds on: the error type, argument checks, CPU thread control and the
geometry shared by the renderer, the classical labeller and the networks (panorama cylinder, DEM ray casting).

``core`` imports nothing of the project; ``data`` <- ``models`` <- ``export`` <- ``bench`` / ``cli`` stand on it.
This ``__init__`` imports nothing, so ``core.errors`` stays importable without torch.
"""
