"""Imported by our process pool's fork server (run._new_pool) before it forks a worker:
the kernels are loaded (numba's cache) once there, by a tiny encode and render, and every
worker, replacements included, starts with them. Importing it anywhere else costs that
encode (about a second) and changes nothing."""

import numpy as np

from .. import encode

_yy, _xx = np.mgrid[0:12, 0:16]
encode(np.stack([_xx * 15.0, _yy * 20.0, 0 * _xx + 128.0], -1).astype(np.uint8)).render(width=24, height=16)
