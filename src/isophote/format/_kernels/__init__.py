"""The format's checks that run over every contour of a big file (numba; NumPy twins beside)."""
