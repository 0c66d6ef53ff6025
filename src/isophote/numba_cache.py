"""Where numba keeps isophote's compiled kernels (``@njit(cache=True)``).

numba's default is a ``__pycache__`` folder beside each kernel's source. That is right for a
source checkout or a user's own venv, but a system-wide or read-only install (a package
manager's site-packages, a container image, a read-only mount) cannot be written there, and
each process would compile every kernel again (half a minute). So, before numba is
imported (``isophote/__init__.py`` calls :func:`configure`):

- if the user set ``NUMBA_CACHE_DIR``, it is left alone;
- else, if the package folder is writable, numba's default stays (nothing is set);
- else ``NUMBA_CACHE_DIR`` becomes the user's cache folder for isophote:
  ``$XDG_CACHE_HOME/isophote/numba``, or ``~/.cache/isophote/numba``.

Writability is ``os.access(folder, W_OK)`` on the kernels' ``__pycache__`` folder (or the
package folder when that does not exist yet): it sees permissions and read-only mounts
(EROFS) without writing anything. Root passes permission checks whatever the mode bits, so
a root process writes into a ``chmod a-w`` tree as numba would; only a read-only mount
stops it. (The tests force the probe's answer to check the decision.)

``NUMBA_CACHE_DIR`` is process-wide: other numba users in the same process then cache in
the same folder, which is harmless (entries are keyed by source path and signature).
"""

from __future__ import annotations

import os
import sys

PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))


def user_cache_dir(env=None) -> str:
    """``$XDG_CACHE_HOME/isophote/numba``, else ``~/.cache/isophote/numba``."""
    env = os.environ if env is None else env
    base = env.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "isophote", "numba")


def package_writable(package_dir: str = PACKAGE_DIR) -> bool:
    """Can numba write its default cache beside the kernels' sources?"""
    probe = os.path.join(package_dir, "_kernels", "__pycache__")
    if not os.path.isdir(probe):
        probe = os.path.join(package_dir, "_kernels")
        if not os.path.isdir(probe):
            probe = package_dir
    return os.access(probe, os.W_OK)


def cache_dir(env=None, writable=None) -> str | None:
    """The NUMBA_CACHE_DIR to set, or None to leave numba's choice. ``writable``: the
    probe's answer (package_writable() when None)."""
    env = os.environ if env is None else env
    if env.get("NUMBA_CACHE_DIR"):
        return None
    if writable is None:
        writable = package_writable()
    return None if writable else user_cache_dir(env)


def configure(writable=None) -> str | None:
    """Apply :func:`cache_dir` to this process; returns the folder set, if any."""
    folder = cache_dir(writable=writable)
    if folder is None:
        return None
    os.environ["NUMBA_CACHE_DIR"] = folder
    config = sys.modules.get("numba.core.config")
    if config is not None:  # numba imported already: its config read the environment
        config.CACHE_DIR = folder
    return folder
