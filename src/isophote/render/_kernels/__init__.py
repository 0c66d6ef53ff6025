"""The renderer's numba kernels: raster (winding bands and crossings), diffuse (distance
fields and the fill), resample, sharpen and colour; render/ orchestrates them.

Twins: a kernel module ``<name>.py`` has its plain NumPy twin beside it as ``<name>_ref.py``,
with the same function names and arguments, written for reading rather than speed; the tests
hold each kernel to its twin on random inputs (tests/render/test_render_kernels.py,
tests/render/test_diffuse_twins.py). The same convention holds in encoder/_kernels/,
format/_coder/ (entropy, entropy_ref) and shared/ (grid, grid_ref).
"""
