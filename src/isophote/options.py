"""Options, with their defaults written once.

Every CLI flag and API keyword comes from these dataclasses; values are in user units
(grey levels on the 0..255 scale, source pixels, degrees) and are checked in ``validate``.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

from .errors import OptionError

# Presets: (y_step, uv_step, alpha_step). "paper" is §1 of the paper: Y every 10 around
# 127 (25 levels), U and V every 5 (49 levels).
PRESETS = {
    "paper": dict(y_step=10.0, uv_step=5.0, alpha_step=10.0),
}


@dataclass(frozen=True)
class EncodeOptions:
    """How a raster becomes contours.

    preset : name in PRESETS; explicit steps or levels override its values.
    y_step, uv_step, alpha_step : level spacing in grey levels; levels sit at 127.5 + k*step
        inside [7.5, 247.5] (between representable 8-bit values, see encoder.levels).
    levels_y, levels_u, levels_v : explicit level lists (override the steps).
    noise : the sample error epsilon in grey levels (§3.1). None = the quantisation error
        of the input, 0.5 for 8-bit (0.5/257 on the 0..255 scale for 16-bit).
    snap : G1 snapping threshold in degrees (§1): joints whose tangents are within this
        angle of opposite are made collinear when the chain stays inside its ribbon.
    min_tolerance, max_tolerance : clamp of the ribbon half-width in source pixels.
    carrato_p : the p of the Carrato 2x formula (§3.2).
    carrato_scale : intensity unit (in grey levels) in which the Carrato differences are
        measured; p = 0.5 acts on differences in this unit (see encoder.mapping).
    """

    preset: str = "paper"
    y_step: float | None = None
    uv_step: float | None = None
    alpha_step: float | None = None
    levels_y: tuple | None = None
    levels_u: tuple | None = None
    levels_v: tuple | None = None
    noise: float | None = None
    snap: float = 20.0
    min_tolerance: float = 0.05
    max_tolerance: float = 0.5
    carrato_p: float = 0.5
    carrato_scale: float = 64.0

    def resolved(self) -> "EncodeOptions":
        """Fill the steps from the preset and validate."""
        if self.preset not in PRESETS:
            raise OptionError(f"unknown preset {self.preset!r} (choose from {', '.join(PRESETS)})")
        base = PRESETS[self.preset]
        out = replace(
            self,
            y_step=self.y_step if self.y_step is not None else base["y_step"],
            uv_step=self.uv_step if self.uv_step is not None else base["uv_step"],
            alpha_step=self.alpha_step if self.alpha_step is not None else base["alpha_step"],
        )
        out.validate()
        return out

    def validate(self) -> None:
        for name in ("y_step", "uv_step", "alpha_step"):
            v = getattr(self, name)
            if v is not None and not (0.5 <= v <= 128):
                raise OptionError(f"{name.replace('_', '-')} must be between 0.5 and 128, got {v}")
        if self.noise is not None and not (0 <= self.noise <= 64):
            raise OptionError(f"noise must be between 0 and 64 grey levels, got {self.noise}")
        if not (0 <= self.snap < 90):
            raise OptionError(f"snap must be between 0 and 90 degrees, got {self.snap}")
        if not (0 < self.min_tolerance <= self.max_tolerance <= 4):
            raise OptionError("need 0 < min-tolerance <= max-tolerance <= 4 pixels")
        if not (0 <= self.carrato_p <= 100) or not (self.carrato_scale > 0):
            raise OptionError("carrato p must be in [0, 100] and its scale positive")
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
    depth: int = 8
    max_pixels: int = 100_000_000

    def validate(self) -> None:
        if self.fill not in FILLS:
            raise OptionError(f"fill must be one of {', '.join(FILLS)}, got {self.fill!r}")
        if self.distance not in DISTANCES:
            raise OptionError(f"distance must be one of {', '.join(DISTANCES)}, got {self.distance!r}")
        if self.depth not in DEPTHS:
            raise OptionError(f"depth must be 8 or 16, got {self.depth}")
        if not (1 <= int(self.supersample) <= 16):
            raise OptionError(f"supersample must be between 1 and 16, got {self.supersample}")
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
