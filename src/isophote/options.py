"""Options, with their defaults written once.

Every CLI flag and API keyword comes from these dataclasses; values are in user units
(grey levels on the 0..255 scale, source pixels, degrees) and are checked in ``validate``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

from .errors import OptionError
from .limits import MAX_PIXELS

# Presets: the values of the fields left at None. What each is for (the measurements behind
# every choice: benchmarks/results/design_choices.md#presets):
#   paper    §1 of the paper: Y every 10 around 127.5 (25 levels), U and V every 5 (49), one
#            global sample error (the quantisation error), no pruning, ribbon <= 0.5 px.
#   compact  the paper's levels, with a per-pixel eps of 3 x the local noise deviation
#            (encoder/noise.py; capped at 0.4 level spacings), a ribbon of up to 1 px, and the
#            U, V loops of under 16 px within 2 eps of their level pruned (encoder/prune.py):
#            the fewest bytes, "high quality" by SSIMULACRA2.
#   high     levels every 3 in Y, U and V over the whole scale (1.5 .. 253.5: dark and bright
#            texture is traced too, encoder/levels.py); the same noise model, chroma pruning
#            within 0.5 eps; on smooth photographs (as balanced, below) levels every 2 with
#            grain smoothing. For masters near "indistinguishable" (SSIMULACRA2 about 90).
#   balanced high's noise model, range and pruning with Y every 6 and U, V every 5: fewer
#            bytes than paper and more faithful on every measure. On photographs smooth almost
#            everywhere (>= 85 % of the luma's pixels with a local noise deviation under 1 grey
#            level: skies, mist, out-of-focus scenes) it takes Y and U, V every 3 and smooths
#            their grain first (smooth_step, smooth_grain; encoder/noise.py adapt_steps), where
#            coarser levels terrace; textured photographs are encoded as before.
# No preset prunes Y (its small loops are texture, which SSIMULACRA2 sees). The default is
# "balanced": isophote's first use is a master that every delivery size is rendered from,
# where fidelity per byte comes first; "paper" keeps the paper's regime (§1), on which the
# speed targets and the applications' benchmarks are stated.
PAPER_RANGE = (7.5, 247.5)  # the paper's levels, 127.5 +- 10k (encoder/levels.py)
FULL_RANGE = (0.5, 254.5)  # the whole 8-bit scale: every two neighbouring values can be separated
PRESETS = {
    "paper": dict(y_step=10.0, uv_step=5.0, alpha_step=10.0, level_range=PAPER_RANGE, local_noise=0.0,
                  prune_area_y=0.0, prune_area_uv=0.0, prune_contrast=0.0, max_tolerance=0.5,
                  smooth_grain=0.0, smooth_step=0.0),
    "compact": dict(y_step=10.0, uv_step=5.0, alpha_step=10.0, level_range=PAPER_RANGE, local_noise=3.0,
                    prune_area_y=0.0, prune_area_uv=16.0, prune_contrast=2.0, max_tolerance=1.0,
                    smooth_grain=0.0, smooth_step=0.0),
    "balanced": dict(y_step=6.0, uv_step=5.0, alpha_step=6.0, level_range=FULL_RANGE, local_noise=3.0,
                     prune_area_y=0.0, prune_area_uv=16.0, prune_contrast=0.5, max_tolerance=1.0,
                     smooth_grain=2.0, smooth_step=3.0),
    "high": dict(y_step=3.0, uv_step=3.0, alpha_step=4.0, level_range=FULL_RANGE, local_noise=3.0,
                 prune_area_y=0.0, prune_area_uv=16.0, prune_contrast=0.5, max_tolerance=1.0,
                 smooth_grain=2.0, smooth_step=2.0),
}
DEFAULT_PRESET = "balanced"  # why: see above
LEVEL_CENTRE = 127.5  # stepped levels sit at LEVEL_CENTRE + k * step (encoder/levels.py)


def level_steps(step: float, low: float, high: float) -> range:
    """The k with LEVEL_CENTRE + k * step inside [low, high] (empty when none fits)."""
    return range(math.ceil((low - LEVEL_CENTRE) / step - 1e-9),
                 math.floor((high - LEVEL_CENTRE) / step + 1e-9) + 1)
AUTO_LOCAL_NOISE = 1.0  # the local_noise that noise="auto" asks for on a preset without one


@dataclass(frozen=True)
class EncodeOptions:
    """How a raster becomes contours.

    preset : name in PRESETS; explicit steps or levels override its values.
    y_step, uv_step, alpha_step : level spacing in grey levels; levels sit at 127.5 + k*step
        inside level_range (between representable 8-bit values, see encoder.levels).
    level_range : (low, high) grey levels, the range the stepped levels fill: the paper's
        (7.5, 247.5), or up to the whole scale (0.5, 254.5). None = the preset's.
    levels_y, levels_u, levels_v : explicit level lists (override the steps).
    noise : the sample error epsilon in grey levels (§3.1). None = the preset's: the
        quantisation error of the input, 0.5 for 8-bit (0.5/257 on the 0..255 scale for
        16-bit), raised per pixel by the local estimate if the preset has one. A number =
        that epsilon everywhere (the local estimate off, unless local_noise is given too:
        then the number is the floor of the per-pixel epsilon). "auto" = the local estimate
        on (local_noise AUTO_LOCAL_NOISE unless the preset has one).
    local_noise : k, the per-pixel epsilon is at least k x the local noise deviation
        (encoder/noise.py); 0 = the paper's global epsilon. None = the preset's.
    noise_floor : (Y,) or (Y, U, V) grey levels, a lower bound on the local noise deviation
        known from the input's making: the JPEG quantisation error of a .jpg input (the CLI
        reads it, imageio.Raster.noise_floor). Used only with local_noise > 0.
    prune_area_y, prune_area_uv, prune_contrast : level crossings of fewer than prune_area
        pixels (prune_area_y for Y and alpha, prune_area_uv for U and V) whose extreme lies
        less than prune_contrast x epsilon beyond the level are flattened before tracing
        (encoder/prune.py); 0 = none. None = the preset's.
    smooth_grain : t, on photographs that are smooth almost everywhere (encoder/noise.py
        adapt_steps), samples with fine grain move towards their blur by up to t x the
        local noise deviation before tracing (encoder/noise.py, "Grain smoothing"); 0 = none.
        None = the preset's.
    smooth_step : Y and U, V level step on photographs that are smooth almost everywhere
        (encoder/noise.py adapt_steps); 0 = the steps everywhere. None = the preset's, or 0
        when steps or levels are given explicitly.
    snap : G1 snapping threshold in degrees (§1): joints whose tangents are within this
        angle of opposite are made collinear when the chain stays inside its ribbon.
    min_tolerance, max_tolerance : clamp of the ribbon half-width in source pixels
        (max_tolerance None = the preset's).
    carrato_p : the p of the Carrato 2x formula (§3.2).
    carrato_scale : intensity unit (in grey levels) in which the Carrato differences are
        measured; p = 0.5 acts on differences in this unit (see encoder.mapping).
    carrato_cubic : weight of the cubic (Catmull-Rom) term added to the midpoints: 1 puts
        Carrato's edge-adaptive weight on Catmull-Rom's cubic base, 2 (the default) on Keys'
        sharper a = -1 cubic, 0 on the paper's linear one (see encoder.mapping).
    memory : the working memory the encoder aims at, a size such as "2G" or "512M" (binary
        units) or a number of bytes: it sizes the units of work (level groups, fit batches,
        channels at a time; encoder/budget.py) and never changes the output bytes.
    """

    preset: str = DEFAULT_PRESET
    y_step: float | None = None
    uv_step: float | None = None
    alpha_step: float | None = None
    level_range: tuple | None = None
    levels_y: tuple | None = None
    levels_u: tuple | None = None
    levels_v: tuple | None = None
    noise: float | str | None = None
    local_noise: float | None = None
    noise_floor: tuple | None = None
    prune_area_y: float | None = None
    prune_area_uv: float | None = None
    prune_contrast: float | None = None
    smooth_grain: float | None = None
    smooth_step: float | None = None
    snap: float = 20.0
    min_tolerance: float = 0.05
    max_tolerance: float | None = None
    carrato_p: float = 0.5
    carrato_scale: float = 64.0
    carrato_cubic: float = 2.0
    memory: str | float = "2G"  # encoder/budget.py DEFAULT_MEMORY

    def resolved(self) -> "EncodeOptions":
        """Fill the fields left at None from the preset, and validate."""
        if self.preset not in PRESETS:
            raise OptionError(f"unknown preset {self.preset!r} (choose from {', '.join(PRESETS)})")
        base = PRESETS[self.preset]
        out = replace(self, **{k: v for k, v in base.items() if getattr(self, k) is None})
        explicit = ("y_step", "uv_step", "levels_y", "levels_u", "levels_v")
        if self.smooth_step is None and any(getattr(self, k) is not None for k in explicit):
            out = replace(out, smooth_step=0.0)  # explicit steps or levels are kept as given
        if isinstance(self.noise, (int, float)) and self.local_noise is None:
            out = replace(out, local_noise=0.0)  # a number is the sample error, as in the paper
        if isinstance(self.noise, str):
            if self.noise.strip().lower() != "auto":
                raise OptionError(f"noise must be a number of grey levels or 'auto', got {self.noise!r}")
            local = self.local_noise
            if local is None:
                local = base["local_noise"] or AUTO_LOCAL_NOISE
            out = replace(out, noise=None, local_noise=local)
        try:
            lo_hi = tuple(float(v) for v in out.level_range)
        except (TypeError, ValueError):
            raise OptionError(f"level-range takes two numbers LOW,HIGH, got {out.level_range!r}") from None
        if len(lo_hi) != 2:
            raise OptionError(f"level-range takes two numbers LOW,HIGH, got {len(lo_hi)}")
        out = replace(out, level_range=lo_hi)
        if out.noise_floor is not None:
            floor = out.noise_floor
            floor = (floor,) if isinstance(floor, (int, float)) else tuple(floor)
            out = replace(out, noise_floor=tuple(float(v) for v in floor))
        out.validate()
        return out

    def validate(self) -> None:
        for name in ("y_step", "uv_step", "alpha_step"):
            v = getattr(self, name)
            if v is not None and not (0.5 <= v <= 128):
                raise OptionError(f"{name.replace('_', '-')} must be between 0.5 and 128, got {v}")
        if self.level_range is not None:
            lo, hi = self.level_range
            if not (0.0 < lo <= hi < 255.0):
                raise OptionError(f"level-range must satisfy 0 < LOW <= HIGH < 255, got {lo},{hi}")
            for name in ("y_step", "uv_step", "alpha_step"):
                step = getattr(self, name)
                if step is not None and len(level_steps(step, lo, hi)) == 0:
                    raise OptionError(f"level-range {lo},{hi} holds no level 127.5 + k x {step} "
                                      f"(--{name.replace('_', '-')})")
        if self.noise is not None and (isinstance(self.noise, str) or not (0 <= self.noise <= 64)):
            raise OptionError(f"noise must be between 0 and 64 grey levels, got {self.noise}")
        if self.local_noise is not None and not (0 <= self.local_noise <= 16):
            raise OptionError(f"local-noise must be between 0 and 16, got {self.local_noise}")
        if self.noise_floor is not None and not (
            1 <= len(self.noise_floor) <= 3 and all(0 <= float(v) <= 64 for v in self.noise_floor)
        ):
            raise OptionError("noise-floor: 1 to 3 values (Y[,U,V]) between 0 and 64 grey levels")
        for name in ("prune_area_y", "prune_area_uv"):
            v = getattr(self, name)
            if v is not None and not (0 <= v <= 1_000_000):
                raise OptionError(f"{name.replace('_', '-')} must be between 0 and 1000000 pixels, got {v}")
        if self.smooth_step is not None and not (self.smooth_step == 0 or 0.5 <= self.smooth_step <= 128):
            raise OptionError(f"smooth-step must be 0 or between 0.5 and 128, got {self.smooth_step}")
        if self.smooth_grain is not None and not (0 <= self.smooth_grain <= 16):
            raise OptionError(f"smooth-grain must be between 0 and 16, got {self.smooth_grain}")
        if self.prune_contrast is not None and not (0 <= self.prune_contrast <= 64):
            raise OptionError(f"prune-contrast must be between 0 and 64, got {self.prune_contrast}")
        if not (0 <= self.snap < 90):
            raise OptionError(f"snap must be between 0 and 90 degrees, got {self.snap}")
        max_tol = self.max_tolerance if self.max_tolerance is not None else self.min_tolerance
        if not (0 < self.min_tolerance <= max_tol <= 4):
            raise OptionError("need 0 < min-tolerance <= max-tolerance <= 4 pixels")
        if not (0 <= self.carrato_p <= 100) or not (self.carrato_scale > 0):
            raise OptionError("carrato p must be in [0, 100] and its scale positive")
        if not (0 <= self.carrato_cubic <= 2):
            raise OptionError(f"carrato cubic must be between 0 and 2, got {self.carrato_cubic}")
        for name in ("levels_y", "levels_u", "levels_v"):
            lv = getattr(self, name)
            if lv is None:
                continue
            if not 1 <= len(lv) <= 1024:
                raise OptionError(f"{name}: between 1 and 1024 levels")
            if any(not (0.0 < float(x) < 255.0) for x in lv):
                raise OptionError(f"{name}: levels must lie strictly between 0 and 255")
            if any(float(b) <= float(a) for a, b in zip(lv, lv[1:])):
                raise OptionError(f"{name}: levels must be strictly increasing")


FILLS = ("diffusion", "linear", "flat")
DISTANCES = ("euclidean", "manhattan", "geodesic")
DEPTHS = (8, 16)


@dataclass(frozen=True)
class RenderOptions:
    """How contours become a raster.

    width, height, scale : output size. One of width/height keeps the aspect ratio, both
        stretch; scale multiplies the (cropped) source size. Default: scale 1.
    crop : (x, y, w, h) in source pixels; the viewport of the master to render.
    fill : "diffusion" (double diffusion, §4.2, with G1 profiles across the isolines),
        "linear" (the paper's straight-line blend of the two distances) or "flat" (Fig. 1b).
    distance : "euclidean", "manhattan" (the paper's §4.2) or "geodesic".
    supersample : s for s x s samples per output pixel, box-filtered (1 = point samples).
        It antialiases flat fill's steps (astronaut, paper, 1x: 36.79 dB at 1, 37.34 at 4);
        the diffusion surface is smooth already and is only blurred by the output pixel's
        box (40.07 dB at 1, 38.22 at 2, 38.03 at 4; benchmarks/results/decoder.md). Below 1x
        a reduction takes at least its own (2 at 1/2, 4 at 1/4 and below: render/levels.py).
    sharpen : K of the enlargement sharpening (render/sharpen.py): above 1x the source
        pixels' box blur, which the contours interpolate, is taken out down to the output
        pixel's; 0 turns it off; no effect at or below 1x, nor with fill "flat".
    depth : 8 or 16 bits per channel.
    max_pixels : refuse larger outputs unless raised explicitly (memory safety).
    """

    width: int | None = None
    height: int | None = None
    scale: float | None = None
    crop: tuple | None = None
    fill: str = "diffusion"
    distance: str = "euclidean"
    supersample: int = 1
    sharpen: float = 0.125
    depth: int = 8
    max_pixels: int = MAX_PIXELS

    def validate(self) -> None:
        if self.fill not in FILLS:
            raise OptionError(f"fill must be one of {', '.join(FILLS)}, got {self.fill!r}")
        if self.distance not in DISTANCES:
            raise OptionError(f"distance must be one of {', '.join(DISTANCES)}, got {self.distance!r}")
        if self.depth not in DEPTHS:
            raise OptionError(f"depth must be 8 or 16, got {self.depth}")
        if not (1 <= int(self.supersample) <= 16):
            raise OptionError(f"supersample must be between 1 and 16, got {self.supersample}")
        if not (0.0 <= float(self.sharpen) <= 1.0):
            raise OptionError(f"sharpen must be between 0 and 1, got {self.sharpen}")
        if self.scale is not None and (self.width is not None or self.height is not None):
            raise OptionError("give either a scale or a width/height, not both")
        if self.scale is not None and not (0 < self.scale <= 1000):
            raise OptionError(f"scale must be positive and at most 1000, got {self.scale}")
        for name in ("width", "height"):
            v = getattr(self, name)
            if v is not None and not (1 <= int(v) <= 1_000_000):
                raise OptionError(f"{name} must be between 1 and 1000000, got {v}")
        if self.crop is not None:
            if len(self.crop) != 4:
                raise OptionError("crop needs four numbers: x,y,w,h")
            if not (self.crop[2] > 0 and self.crop[3] > 0):
                raise OptionError("crop width and height must be positive")


@dataclass(frozen=True)
class WriteOptions:
    """How a raster is written.

    quality : JPEG and WebP quality, 1..100 on Pillow's scale (95, the value isophote has
        always written: near the top of the scale, where a master's renders belong). PNG,
        TIFF and BMP are lossless and take none.
    """

    quality: int = 95

    def validate(self) -> None:
        if not (isinstance(self.quality, int) and 1 <= self.quality <= 100):
            raise OptionError(f"quality must be an integer between 1 and 100, got {self.quality}")


def option_names(cls) -> list[str]:
    return [f.name for f in fields(cls)]


def make(cls, options: dict):
    """cls(**options), with unknown keywords reported as an OptionError naming them."""
    unknown = sorted(set(options) - set(option_names(cls)))
    if unknown:
        raise OptionError(
            f"unknown option{'s' if len(unknown) > 1 else ''} {', '.join(unknown)} "
            f"(known: {', '.join(option_names(cls))})"
        )
    return cls(**options)
