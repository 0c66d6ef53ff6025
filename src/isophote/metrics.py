"""Fidelity metrics: how far a rendering is from its original.

Arrays in, numbers out. Every function takes a reference and a test image of the same
shape, ``(H, W)`` or ``(H, W, C)`` with C = 1 (grey), 2 (grey + alpha), 3 (RGB) or
4 (RGBA), samples on the 0..255 scale (uint8, or float with fractions, as ``render``
returns them). The metrics judge what a viewer sees:

- samples are clipped to [0, 255] (a display cannot show an overshoot);
- alpha is composited over mid-grey (0.5, SSIMULACRA2's own background), so colour
  hidden under zero alpha does not count;
- grey images are compared as grey where the metric allows it (PSNR, SSIM) and replicated
  to RGB where it needs colour (SSIMULACRA2, FLIP); PSNR and SSIM give the same answer
  either way.

=============  =========================  ============  ================================
metric         better                     identical     package
=============  =========================  ============  ================================
psnr           higher (dB)                inf           numpy
ssim           higher, at most 1          1.0           scikit-image
ssimulacra2    higher, at most 100        100.0         ``ssimulacra2`` (pure Python)
flip           lower, 0..1                0.0           ``flip-evaluator`` (LDR-FLIP)
=============  =========================  ============  ================================

SSIMULACRA2 reads as: 90 visually lossless at 1:1, 70 high quality, 50 medium quality,
30 low quality. It is the slowest metric, then FLIP, SSIM and PSNR (measured:
benchmarks/results/design_choices.md#metric-speed).

The optional packages come with ``pip install isophote[metrics]``; a metric whose package
is missing raises :class:`~isophote.errors.OptionError` naming that extra.
"""

from __future__ import annotations

import math
import os
import tempfile

import numpy as np

from .errors import InputError, OptionError

MIN_SIDE = {"psnr": 1, "ssim": 7, "ssimulacra2": 8, "flip": 1}
# ssim: scikit-image's 7 x 7 window must fit. ssimulacra2: the reference implementation
# stops at scales under 8 pixels, and with no scale at all it answers 100 whatever the
# images are; we refuse instead of returning that meaningless 100.

_EXTRA = "pip install isophote[metrics]"


# --------------------------------------------------------------------------- inputs


def _as_samples(a, name: str) -> np.ndarray:
    """One image as (H, W, C) float64 on 0..255, clipped, with C in 1..4."""
    a = np.asarray(a)
    if a.dtype == bool or not (np.issubdtype(a.dtype, np.integer) or np.issubdtype(a.dtype, np.floating)):
        raise InputError(f"{name}: expected numeric samples, got dtype {a.dtype}")
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3 or not 1 <= a.shape[2] <= 4:
        raise InputError(f"{name}: expected an (H, W) or (H, W, 1..4) array, got shape {a.shape}")
    if a.shape[0] < 1 or a.shape[1] < 1:
        raise InputError(f"{name}: image has no pixels (shape {a.shape})")
    a = a.astype(np.float64)
    if not np.isfinite(a).all():
        raise InputError(f"{name}: samples must be finite (found NaN or infinity)")
    return np.clip(a, 0.0, 255.0)


def _pair(ref, test, metric: str | None = None, composite: bool = True):
    """Validate a (reference, test) pair; return both as (H, W, C) float64 on 0..255.

    With ``composite``, alpha is blended over mid-grey and dropped, so C is 1 or 3.
    """
    r = _as_samples(ref, "reference")
    t = _as_samples(test, "test")
    if r.shape != t.shape:
        raise InputError(f"reference and test differ in shape: {r.shape} vs {t.shape}")
    if metric is not None and min(r.shape[:2]) < MIN_SIDE[metric]:
        raise InputError(
            f"{metric} needs images of at least {MIN_SIDE[metric]} x {MIN_SIDE[metric]} "
            f"pixels, got {r.shape[1]} x {r.shape[0]}"
        )
    if composite:
        r, t = _composite(r), _composite(t)
    return r, t


def _composite(a: np.ndarray, background: float = 127.5) -> np.ndarray:
    """(H, W, C) -> colour channels, alpha (C = 2, 4) blended over ``background``."""
    if a.shape[2] in (2, 4):
        alpha = a[..., -1:] / 255.0
        return a[..., :-1] * alpha + background * (1.0 - alpha)
    return a


def _rgb(a: np.ndarray) -> np.ndarray:
    """(H, W, 1 or 3) -> (H, W, 3)."""
    return np.repeat(a, 3, axis=2) if a.shape[2] == 1 else a


# --------------------------------------------------------------------------- metrics


def psnr(ref, test, peak: float = 255.0) -> float:
    """Peak signal-to-noise ratio in dB over all samples of all colour channels.

    Parameters
    ----------
    ref, test : (H, W) or (H, W, C) array on 0..255
    peak : float
        The largest possible sample value.

    Returns
    -------
    float
        ``10 log10(peak^2 / MSE)``; ``inf`` for identical images. A difference of one grey
        level everywhere gives 20 log10(255) = 48.13 dB.
    """
    if not peak > 0:
        raise OptionError(f"psnr peak must be positive, got {peak}")
    r, t = _pair(ref, test, "psnr")
    mse = float(np.mean((r - t) ** 2))
    if mse == 0.0:
        return math.inf
    return 10.0 * math.log10(peak * peak / mse)


def ssim(ref, test) -> float:
    """Structural similarity (Wang et al. 2004), mean over pixels and colour channels.

    Uses scikit-image's ``structural_similarity`` with the paper's settings (Gaussian
    window of sigma 1.5, population covariance, K1 = 0.01, K2 = 0.03) and data_range 255.
    Images must be at least 7 x 7.

    Returns
    -------
    float
        1.0 for identical images; lower is worse (it can go below 0).
    """
    from skimage.metrics import structural_similarity

    r, t = _pair(ref, test, "ssim")
    kwargs = dict(data_range=255.0, gaussian_weights=True, sigma=1.5, use_sample_covariance=False)
    if r.shape[2] == 1:
        return float(structural_similarity(r[..., 0], t[..., 0], **kwargs))
    return float(structural_similarity(r, t, channel_axis=2, **kwargs))


def ssimulacra2(ref, test) -> float:
    """SSIMULACRA 2 score (Sneyers 2022-2023), through the ``ssimulacra2`` package.

    Returns
    -------
    float
        100 for identical images; 90 visually lossless at 1:1, 70 high quality, 50 medium,
        30 low; it can go negative for very poor images.

    Notes
    -----
    The package reads its images from files, so both are written as temporary 8-bit RGB
    BMPs (lossless like PNG, without the compression time; samples rounded to integers,
    grey replicated to RGB). The score is computed on up
    to six scales, halving the image until a side falls under 8 pixels; images with a side
    under 256 pixels use fewer scales, as in the reference implementation, so compare scores
    only between images of similar size. Images under 8 x 8 are refused. Pure Python, the
    slowest metric (measured: benchmarks/results/design_choices.md#metric-speed).
    """
    try:
        from ssimulacra2 import compute_ssimulacra2
    except ImportError:
        raise OptionError(f"ssimulacra2 needs the 'ssimulacra2' package: {_EXTRA}") from None
    from .imageio import write_image

    r, t = _pair(ref, test, "ssimulacra2")
    with tempfile.TemporaryDirectory(prefix="isophote-ssimulacra2-") as folder:
        paths = os.path.join(folder, "reference.bmp"), os.path.join(folder, "test.bmp")
        write_image(paths[0], _rgb(r))
        write_image(paths[1], _rgb(t))
        return float(compute_ssimulacra2(paths[0], paths[1]))


def flip(ref, test) -> float:
    """Mean LDR-FLIP error (Andersson et al. 2020), through ``flip-evaluator``.

    Both images are taken as sRGB, shown at FLIP's default 67 pixels per degree (a 0.7 m
    wide 4K screen seen from 0.7 m).

    Returns
    -------
    float
        0.0 for identical images, up to 1.0; lower is better.
    """
    try:
        import flip_evaluator
    except ImportError:
        raise OptionError(f"flip needs the 'flip-evaluator' package: {_EXTRA}") from None

    r, t = _pair(ref, test, "flip")
    r32 = np.ascontiguousarray(_rgb(r) / 255.0, dtype=np.float32)
    t32 = np.ascontiguousarray(_rgb(t) / 255.0, dtype=np.float32)
    _, mean_error, _ = flip_evaluator.evaluate(
        r32, t32, "LDR", inputsRGB=True, applyMagma=False, computeMeanError=True
    )
    return float(mean_error)


# One row per metric: compare() and callers that list metrics read this table.
METRICS = {
    "psnr": psnr,
    "ssim": ssim,
    "ssimulacra2": ssimulacra2,
    "flip": flip,
}


def compare(ref, test, metrics=("psnr", "ssim", "ssimulacra2", "flip")) -> dict:
    """Several metrics at once.

    Parameters
    ----------
    ref, test : (H, W) or (H, W, C) array on 0..255
    metrics : iterable of str
        Names from :data:`METRICS`.

    Returns
    -------
    dict
        metric name -> float, in the order asked.
    """
    if isinstance(metrics, str):
        metrics = (metrics,)
    metrics = tuple(metrics)
    unknown = [m for m in metrics if m not in METRICS]
    if unknown:
        raise OptionError(f"unknown metric {unknown[0]!r} (choose from {', '.join(METRICS)})")
    _pair(ref, test)  # one clear error for a bad pair before any slow metric runs
    return {m: METRICS[m](ref, test) for m in metrics}


def difference_image(ref, test, gain: float = 4.0) -> np.ndarray:
    """What was lost, made visible: ``|ref - test| * gain``, clipped to 0..255.

    Parameters
    ----------
    ref, test : (H, W) or (H, W, C) array on 0..255
    gain : float
        Amplification; 4 makes a 16-level error a quarter of full scale.

    Returns
    -------
    (H, W, C) float64 ndarray on 0..255
        Same channels as the inputs (alpha included, not composited); 0 where they agree.
        Write it with ``isophote.imageio.write_image``.
    """
    if not (gain > 0 and math.isfinite(gain)):
        raise OptionError(f"difference gain must be a positive number, got {gain}")
    r, t = _pair(ref, test, composite=False)
    return np.clip(np.abs(r - t) * gain, 0.0, 255.0)


__all__ = ["psnr", "ssim", "ssimulacra2", "flip", "compare", "difference_image", "METRICS"]
