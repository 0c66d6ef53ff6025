"""Per-sample error (§3.1) estimated from the image itself (§6), and the plane's preparation.

The paper encodes with one global sample error eps (§3.1: "a simple global noise value") and
names local models as the better choice; §6 asks for a resolution that follows local
smoothness. Here every pixel gets its own eps, which the ribbon (ribbon.py, eq. 1) turns
into a positional tolerance eps / |grad phi|: where the image is noisy or finely textured
the ribbon widens and the fitter needs fewer, longer Béziers; where it is clean and smooth
the ribbon stays as tight as the quantisation allows.

Noise model
    sigma(x)  the local standard deviation of the high-frequency residual: the image
              filtered with Immerkær's kernel (the difference of two Laplacians, blind to
              planes and nearly blind to straight edges; for white noise of deviation s its
              output, divided by 6, has deviation s), summarised robustly as
              1.4826 x the median of |residual| over WINDOW x WINDOW windows on a
              STRIDE-pixel lattice, interpolated bilinearly to every pixel. The median keeps
              edges and lines (a minority of a window's samples) from reading as noise;
              texture finer than the window does read as noise, which is what it is to a
              contour coder.
    floor     a lower bound on sigma for the channel, known from how the input was made:
              the JPEG quantisation error of a .jpg input
              (:func:`isophote.imageio.dct_quantisation_error`, passed on by the CLI as the
              ``noise_floor`` option), else 0.
    eps(x)  = max(eps0, min(k * max(sigma(x), floor), cap))
              eps0 is the global error (the quantisation error of the input, 0.5 for 8-bit,
              or the user's --noise); k is ``local_noise``; cap = CAP_FRACTION x the
              smallest level spacing, so that the ribbons of neighbouring levels (spaced
              step / |grad phi| apart) cannot overlap, whatever the texture.

Grain smoothing (``smooth_grain`` t > 0, issue 26)
    Where the image is smooth and its grain is fine (a sky, an out-of-focus background), an
    isoline of a level the gradient crosses slowly wanders with the grain by
    sigma / |grad| px, far beyond the ribbon's max_tolerance, so the fitter follows it and
    the render between such contours shows blotches the size of the wander (DarkestHour,
    balanced: SSIMULACRA2 69.1). Before tracing, every sample moves towards the plane's
    Gaussian blur (GRAIN_SIGMA px) by at most
        b(x) = t * sigma(x) * clip(2 - sigma(x) / GRAIN_FULL, 0, 1)
               * clip(sigma(x) / (|grad blur(x)| * GRAIN_WANDER) - 1, 0, 1):
    the move stays within t deviations of the grain (edges, which the blur moves by much more,
    move by only that), it is whole where sigma is under GRAIN_FULL grey levels and gone
    where it is twice that (texture, which reads as noise to the estimate, keeps its
    samples), and it is whole where the grain moves the isoline by more than
    2 GRAIN_WANDER px, gone where by less than GRAIN_WANDER.

Finer levels on smooth photographs (``smooth_step`` > 0, issue 26)
    A photograph that is smooth almost everywhere (a sky, mist, an out-of-focus scene) costs
    few bytes a level: its isolines are long and straight. There the preset's coarse steps are
    what limits it (the fill between levels 6 apart shows in a dark sky: DarkestHour balanced,
    SSIMULACRA2 69.1), while on textured photographs finer levels cost bytes in proportion to
    the texture. :func:`adapt_steps` gives Y and U, V the step ``smooth_step`` when at least
    SMOOTH_SHARE of the luma's pixels have a local noise deviation under GRAIN_FULL and its
    mean gradient is under SMOOTH_GRADIENT (:func:`is_smooth`), and keeps grain smoothing for
    such photographs only.

With ``local_noise == 0``, no pruning and no grain smoothing (the "paper" preset)
:func:`prepare_plane` returns its inputs untouched: the paper's global eps.
"""

from __future__ import annotations

import numpy as np

from .. import threads
from ._kernels.median import window_medians
from .prune import prune_extrema

WINDOW = 16  # pixels: the robust estimate's window
STRIDE = 8  # pixels between window centres (windows overlap by half)
CAP_FRACTION = 0.4  # eps <= 0.4 x level spacing: neighbouring ribbons keep 20 % clear
GRAIN_SIGMA = 1.5  # px: the blur the samples move towards
GRAIN_FULL = 1.0  # grey levels of noise deviation under which the move is whole
GRAIN_WANDER = 1.0  # px of isoline wander (sigma / |grad|) above which the move starts
SMOOTH_SHARE = 0.85  # share of fine-grained luma pixels that makes a photograph "smooth"
SMOOTH_GRADIENT = 4.0  # grey levels a pixel: the most mean |grad| (1 px blur) of a smooth one
SMOOTH_RUN_PIXELS = 1 << 20  # pixels a step over a whole plane takes at a time (plane_runs)
MAD_TO_SIGMA = 1.4826  # sigma of a normal distribution / its median absolute deviation

# Immerkær (1996), "Fast noise variance estimation": L2 - 2 L1 of two Laplacians. Its
# response to a plane is 0, its squared weights sum to 36.
IMMERKAER = np.array([[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]]) / 6.0


def residual(plane: np.ndarray) -> np.ndarray:
    """Immerkær's high-pass residual of a (H, W) plane (edge samples repeated outside),
    scaled so that white noise of deviation s gives a residual of deviation s."""
    from scipy import ndimage

    return ndimage.convolve(np.asarray(plane, np.float64), IMMERKAER, mode="nearest")


def local_noise(plane: np.ndarray, window: int = WINDOW, stride: int = STRIDE) -> np.ndarray:
    """Robust local noise deviation sigma, (H, W) float64 in the plane's units.

    Parameters
    ----------
    plane : (H, W) ndarray
        One channel on the 0..255 scale.
    window, stride : int
        The median of |residual| is taken over window x window pixels centred every
        ``stride`` pixels, then interpolated bilinearly to the pixel centres.
    """
    return noise_rows(plane, window, stride)(0, np.shape(plane)[0])


class NoiseRows:
    """local_noise's plane, rows at a time: rows(a, b) is local_noise(plane)[a:b], the same
    bits (each sample is interpolated from the lattice on its own), from the lattice of
    window medians alone (1/64 of the plane at STRIDE 8)."""

    def __init__(self, coarse, yy, xx, constant=None):
        self.coarse, self.yy, self.xx, self.constant = coarse, yy, xx, constant

    def __call__(self, a: int, b: int) -> np.ndarray:
        from scipy import ndimage

        if self.constant is not None:
            return np.full((len(self.yy[a:b]), self.xx.shape[0]), self.constant)
        coords = np.meshgrid(self.yy[a:b], self.xx, indexing="ij")
        return ndimage.map_coordinates(self.coarse, coords, order=1, mode="nearest")


def noise_rows(plane: np.ndarray, window: int = WINDOW, stride: int = STRIDE) -> NoiseRows:
    """local_noise as a row source (NoiseRows): the lattice of window medians is computed
    here, the per-pixel interpolation when rows are asked for."""
    from scipy import ndimage

    r = residual(plane)
    np.abs(r, out=r)
    h, w = r.shape
    win = min(window, h, w)
    if win < 3:
        return NoiseRows(None, np.zeros(h), np.zeros(w), MAD_TO_SIGMA * float(np.median(r)))
    ny, nx = -(-h // stride), -(-w // stride)
    pad_lo = win // 2
    pad_y = max(0, (ny - 1) * stride + stride // 2 + win - win // 2 - h)
    pad_x = max(0, (nx - 1) * stride + stride // 2 + win - win // 2 - w)
    rp = np.pad(r, ((pad_lo, pad_y), (pad_lo, pad_x)), mode="reflect" if min(h, w) > pad_lo else "edge")
    cy = stride // 2 + np.arange(ny) * stride  # centre rows in image coordinates
    cx = stride // 2 + np.arange(nx) * stride
    del r
    coarse = MAD_TO_SIGMA * medians(rp, (cy - win // 2 + pad_lo).astype(np.int64),
                                    (cx - win // 2 + pad_lo).astype(np.int64), win)
    del rp
    yy = np.clip((np.arange(h) - stride // 2) / stride, 0, ny - 1)
    xx = np.clip((np.arange(w) - stride // 2) / stride, 0, nx - 1)
    return NoiseRows(coarse, yy, xx)


def medians(rp, rows, cols, win, workers: int | None = None) -> np.ndarray:
    """window_medians (_kernels/median.py) of the lattice's rows in ``workers`` runs at a time
    (default: the threads this process may use, isophote.threads): each window's median is
    its own, so the same values whatever the runs."""
    n = threads.available() if workers is None else max(1, int(workers))
    cuts = np.linspace(0, rows.shape[0], min(n, max(rows.shape[0], 1)) + 1).astype(np.int64)
    if cuts.shape[0] <= 2:
        return window_medians(rp, rows, cols, win)
    with threads.pool(n) as pool:
        parts = list(pool.map(lambda ab: window_medians(rp, rows[ab[0]:ab[1]], cols, win), zip(cuts[:-1], cuts[1:])))
    return np.concatenate(parts, axis=0)


def sample_error(plane, eps0, levels, local, floor=0.0) -> np.ndarray:
    """eps(x) of the module docstring: (H, W) float64 grey levels."""
    return error_rows(plane, eps0, levels, local, floor)(0, np.shape(plane)[0])


class ErrorRows:
    """sample_error's plane, rows at a time: rows(a, b) is sample_error(...)[a:b], the same
    bits, from local_noise's lattice (NoiseRows). The encoder's strips ask each for its own
    rows, so that the per-pixel errors (8 bytes a pixel) are not held through the march."""

    def __init__(self, sigma: NoiseRows, eps0, cap, local, floor):
        self.sigma, self.eps0, self.cap, self.local, self.floor = sigma, eps0, cap, local, floor

    def __call__(self, a: int, b: int) -> np.ndarray:
        est = self.local * np.maximum(self.sigma(a, b), self.floor)
        if self.cap is not None:
            est = np.minimum(est, self.cap)
        return np.maximum(est, self.eps0)


def error_rows(plane, eps0, levels, local, floor=0.0) -> ErrorRows:
    """sample_error as a row source (ErrorRows)."""
    levels = np.asarray(levels, np.float64)
    cap = CAP_FRACTION * float(np.min(np.diff(levels))) if levels.size > 1 else None
    return ErrorRows(noise_rows(plane), eps0, cap, local, float(floor))


def smooth_grain(plane: np.ndarray, t: float, sigma: np.ndarray | None = None) -> np.ndarray:
    """The plane with its fine grain in smooth regions taken out (module docstring, "Grain
    smoothing"): a new (H, W) float64 array, every sample within t x its local noise
    deviation ``sigma`` (estimated when not given) of the input."""
    from scipy import ndimage

    f = np.asarray(plane, np.float64)
    if t <= 0 or min(f.shape) < 2:
        return f.copy()
    noise = noise_rows(f) if sigma is None else (lambda a, b, s=np.asarray(sigma, np.float64): s[a:b])
    g = ndimage.gaussian_filter(f, GRAIN_SIGMA, mode="nearest")
    out = np.empty_like(f)
    # a run of rows at a time (the whole formula's temporaries were about 60 bytes a pixel),
    # each sample's value the whole formula's: the gradient rows from their neighbours in g
    for a, b in plane_runs(f.shape):
        grad = gradient_rows(g, a, b)
        s = noise(a, b)
        with np.errstate(divide="ignore", invalid="ignore"):
            wander = np.where(grad > 0, s / np.maximum(grad, 1e-300), np.inf)
        bound = (t * s * np.clip(2.0 - s / GRAIN_FULL, 0.0, 1.0)
                 * np.clip(np.nan_to_num(wander / GRAIN_WANDER - 1.0, posinf=1.0), 0.0, 1.0))
        out[a:b] = f[a:b] + np.clip(g[a:b] - f[a:b], -bound, bound)
    return out


def is_smooth(luma: np.ndarray) -> bool:
    """Whether a photograph is smooth almost everywhere: at least SMOOTH_SHARE of its luma's
    pixels have a local noise deviation under GRAIN_FULL, and its mean gradient (after a
    1 px Gaussian) is under SMOOTH_GRADIENT. The contours' total length is the integral of
    |grad| over the image divided by the step (the coarea formula), so the gradient says what
    finer levels would cost: Grey (clean, 96 % fine-grained, but planks everywhere, mean
    |grad| 7.0) would double its bytes at levels every 4; the smooth photographs of the wide
    corpus have 0.3-2.5."""
    luma = np.asarray(luma, np.float64)
    if min(luma.shape) < 3:  # too small to have a gradient, or a region to smooth
        return False
    return fine_share(luma) >= SMOOTH_SHARE and mean_gradient(luma) < SMOOTH_GRADIENT


# is_smooth's two measures, a run of rows at a time (whole-plane temporaries were 40 bytes a
# pixel: 600 MiB of a 16 MP photograph) with the whole computation's bits.


def fine_share(luma: np.ndarray) -> float:
    """np.mean(local_noise(luma) < GRAIN_FULL): the fine-grained pixels counted run by run."""
    noise = noise_rows(luma)
    fine = sum(int(np.count_nonzero(noise(a, b) < GRAIN_FULL)) for a, b in plane_runs(luma.shape))
    return fine / luma.size


def mean_gradient(luma: np.ndarray) -> float:
    """np.hypot(*np.gradient(gaussian_filter(luma, 1))).mean() (at least 2 rows): each run of
    gradient rows made from its blurred rows and their neighbours."""
    from scipy import ndimage

    g = ndimage.gaussian_filter(luma, 1.0)
    grad = np.empty_like(g)
    for a, b in plane_runs(g.shape):
        grad[a:b] = gradient_rows(g, a, b)
    return float(grad.mean())


def plane_runs(shape, pixels: int | None = None) -> list:
    """Runs [a, b) of the rows of an (H, W) plane, about ``pixels`` (SMOOTH_RUN_PIXELS when
    None) pixels each, at least a row: what the steps over a whole plane take at a time."""
    h, w = int(shape[0]), int(shape[1])
    step = max(1, (SMOOTH_RUN_PIXELS if pixels is None else int(pixels)) // max(w, 1))
    return [(a, min(a + step, h)) for a in range(0, h, step)]


def gradient_rows(g: np.ndarray, a: int, b: int) -> np.ndarray:
    """np.hypot(*np.gradient(g))[a:b] (g at least 2 rows), from rows a - 1 .. b of g alone:
    the same bits (central differences inside, one-sided at the plane's first and last row)."""
    lo, hi = max(a - 1, 0), min(b + 1, g.shape[0])
    gy, gx = np.gradient(g[lo:hi])
    return np.hypot(gy[a - lo : b - lo], gx[a - lo : b - lo])


def adapt_steps(opts, luma: np.ndarray):
    """``opts`` as the photograph asks: when it is smooth (module docstring), y_step and
    uv_step set to ``opts.smooth_step`` (never coarser than they were); when it is not, grain
    smoothing off (it takes texture that reads as noise with it: BytheWater, balanced,
    SSIMULACRA2 81.4 without it, 79.2 with it)."""
    from dataclasses import replace

    fine = float(getattr(opts, "smooth_step", 0.0) or 0.0)
    grain = float(getattr(opts, "smooth_grain", 0.0) or 0.0)
    if (fine <= 0 and grain <= 0) or luma.size == 0:
        return opts
    if not is_smooth(luma):
        return replace(opts, smooth_grain=0.0) if grain > 0 else opts
    if fine <= 0:
        return opts
    return replace(opts, y_step=min(fine, opts.y_step), uv_step=min(fine, opts.uv_step))


def prepare_plane(name, plane, eps, levels, opts):
    """prepare_plane_rows with the per-sample error made whole: (plane, eps), eps a float
    or an (H, W) float64 array."""
    plane, eps = prepare_plane_rows(name, plane, eps, levels, opts)
    return plane, (eps(0, plane.shape[0]) if callable(eps) else eps)


def prepare_plane_rows(name, plane, eps, levels, opts):
    """The plane and its per-sample error as the contour finder should see them: (plane,
    eps), eps the float given or a row source of the per-pixel error (ErrorRows: rows(a, b)
    of the (H, W) plane of errors, computed when asked).

    ``opts.local_noise`` > 0: eps becomes the per-pixel :func:`sample_error` (with the
    channel's ``opts.noise_floor``); ``opts.prune_area_y`` (Y, A) or ``prune_area_uv`` (U, V)
    > 0: extrema below the noise are flattened (prune.py) so that their small loops are never
    traced; ``opts.smooth_grain`` > 0: the grain of smooth regions is taken out first
    (:func:`smooth_grain`; not alpha). Otherwise (the paper)
    both come back unchanged.

    Parameters
    ----------
    name : "Y", "U", "V" or "A"
    plane : (H, W) float64, the channel on 0..255
    eps : float, the global sample error (eps0)
    levels : (L,) the channel's levels
    opts : resolved EncodeOptions
    """
    local = float(opts.local_noise or 0.0)
    prune_area = float((opts.prune_area_uv if name in ("U", "V") else opts.prune_area_y) or 0.0)
    grain = float(getattr(opts, "smooth_grain", 0.0) or 0.0) if name != "A" else 0.0
    if local <= 0 and prune_area <= 0 and grain <= 0:
        return plane, eps
    if grain > 0:
        plane = smooth_grain(plane, grain)
    if local > 0:
        eps = error_rows(plane, eps, levels, local, channel_floor(opts.noise_floor, name))
    if prune_area > 0 and opts.prune_contrast > 0:
        # the thresholds, a run of the errors' rows at a time (their temporaries were 30 bytes
        # a pixel; ErrorRows gives the same bits whatever the rows), scaled in place
        thr = _rows_whole(eps, plane.shape) if callable(eps) else np.array(eps, np.float64)
        plane = prune_extrema(plane, levels, prune_area, np.multiply(thr, opts.prune_contrast, out=thr))
        del thr
    return plane, eps


def _rows_whole(rows, shape) -> np.ndarray:
    """The (H, W) plane of a row source (rows(a, b) its rows a..b), SMOOTH_RUN_PIXELS at a time."""
    out = np.empty(shape)
    for a, b in plane_runs(shape):
        out[a:b] = rows(a, b)
    return out


def channel_floor(noise_floor, name) -> float:
    """The floor of channel ``name`` from a (Y,) or (Y, U, V) tuple (alpha gets none)."""
    if not noise_floor or name == "A":
        return 0.0
    i = "YUV".index(name)
    return float(noise_floor[min(i, len(noise_floor) - 1)])
