"""``isophote batch``: photographs and frame sequences -> masters and every delivery.

    >>> import isophote
    >>> summary = isophote.batch(["frames/"], "out", deliver="sd,hd,uhd,phone")
    >>> from distributed import Client                      # pip install 'isophote[dask]'
    >>> with Client("tcp://scheduler:8786") as client:
    ...     isophote.batch(["frames/"], "out", executor=client.get_executor())

Modules: inputs (INPUT arguments, natural sort), deliveries (sizes, --fit geometry),
manifest (OUTDIR/manifest.json, what is fresh), memory (an item's budget), item (one item,
as a worker runs it), run (the executor loop: retries, resume), cli (the subcommand).
Importing this package starts no pool and imports no Dask.
"""

import sys as _sys
import types as _types

from .run import DEFAULT_DELIVERIES, Summary, batch


class _CallableModule(_types.ModuleType):
    """``isophote.batch`` is this package once imported (Python sets the attribute), and
    also the function: calling the package calls :func:`isophote.batch.run.batch`."""

    def __call__(self, *args, **kwargs):
        return batch(*args, **kwargs)


_sys.modules[__name__].__class__ = _CallableModule

__all__ = ["batch", "Summary", "DEFAULT_DELIVERIES"]
