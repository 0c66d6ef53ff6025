"""Errors raised by isophote. The CLI maps every IsophoteError to exit status 2."""


class IsophoteError(Exception):
    """Base class: bad input or options, reported to users in one line."""


class InputError(IsophoteError):
    """An input raster could not be read or is unusable (empty, truncated, not an image)."""


class FormatError(IsophoteError):
    """An .isoph (or SVG) file is malformed, truncated, corrupted or of an unknown version."""


class OptionError(IsophoteError):
    """An option has a bad value or options contradict each other."""


class LimitError(IsophoteError):
    """A declared or requested size exceeds a documented limit."""
