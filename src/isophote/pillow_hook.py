"""Registers the .isoph Pillow plugin (pillow_plugin.py) without importing Pillow.

``import isophote`` must make ``PIL.Image.open("x.isoph")`` work, but must not import Pillow
itself (``isophote --help`` and numpy-only users should not pay its import time; measured:
benchmarks/results/design_choices.md#pillow-import). So:
if ``PIL.Image`` is imported already, the plugin is registered now; otherwise a finder on
``sys.meta_path`` waits for ``PIL.Image`` to be imported (by anyone, at any time), lets it
execute, registers the plugin, and removes itself. Nothing else is looked at: every other
import goes past it with one string comparison.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import sys

TARGET = "PIL.Image"


def _register() -> None:
    try:
        from .pillow_plugin import register
    except ImportError:  # a broken Pillow: reading .isoph through it is then not offered
        return
    register()


class _Loader(importlib.abc.Loader):
    """PIL.Image's own loader, with the plugin registered once the module has executed."""

    def __init__(self, loader):
        self._loader = loader

    def create_module(self, spec):
        return self._loader.create_module(spec)

    def exec_module(self, module):
        self._loader.exec_module(module)
        _register()


class _Finder(importlib.abc.MetaPathFinder):
    def __init__(self):
        self._busy = False

    def find_spec(self, name, path=None, target=None):
        if name != TARGET or self._busy:
            return None
        self._busy = True
        try:
            spec = importlib.machinery.PathFinder.find_spec(name, path)
        finally:
            self._busy = False
        _remove()
        if spec is None or spec.loader is None or not hasattr(spec.loader, "exec_module"):
            return spec
        spec.loader = _Loader(spec.loader)
        return spec


_FINDER = _Finder()


def _remove() -> None:
    try:
        sys.meta_path.remove(_FINDER)
    except ValueError:
        pass


def install() -> None:
    """Register now if Pillow is loaded, else when it is (idempotent)."""
    if TARGET in sys.modules:
        _register()
    elif _FINDER not in sys.meta_path:
        sys.meta_path.insert(0, _FINDER)
