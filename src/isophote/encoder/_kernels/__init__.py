"""The encoder's numba kernels, one module a stage (marching, anchors, fit, prune, regions,
enclose); the stage modules in encoder/ validate and document, these compute.

Twins: a kernel module ``<name>.py`` with a plain NumPy/Python twin has it beside it as
``<name>_ref.py``, with the same function names (``fit.fit_many_kernel`` aside, whose twin
``fit_ref.fit_polyline`` fits one polyline), written for reading rather than speed; the
tests hold each kernel to its twin on random inputs. The same holds in render/_kernels/,
format/_coder/ (entropy, entropy_ref) and shared/ (grid, grid_ref).
"""
