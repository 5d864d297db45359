"""Imported first by the cheap per-site job adapters (``import skidsim._lean``): start-up cost only, no number
changes.

SciPy (>= 1.15) decorates its public functions with ``xp_capabilities``, which parses each function's NumPy
docstring (``FunctionDoc``) at import time to append a table of supported array backends: about 0.15 s of the
import of ``scipy.fft`` + ``scipy.ndimage`` and 0.25 s of ``scipy.signal``, for docstrings that a batch job never
reads. This module hooks the import of ``scipy._lib._array_api`` (nothing is imported here, so a job that never
imports SciPy pays nothing) and gives the decorator a stand-in that keeps each docstring as it is (without the
table). Only the process that imports this module is affected; with a SciPy without the decorator, nothing
changes.
"""

from __future__ import annotations

import sys
from importlib.abc import MetaPathFinder
from importlib.util import find_spec

_TARGET = "scipy._lib._array_api"


class _UnparsedDoc:
    """Stands for ``scipy._lib._docscrape.FunctionDoc`` in ``xp_capabilities``: the docstring unparsed, unchanged
    (the decorator appends its note to a section nobody prints, and writes back ``str(doc)`` minus its first
    line)."""

    def __init__(self, func, *args, **kwargs):
        self._doc = getattr(func, "__doc__", None) or ""

    def __getitem__(self, section):
        return []

    def __str__(self):
        return "\n" + self._doc


def _patch(module) -> None:
    if hasattr(module, "FunctionDoc"):
        module.FunctionDoc = _UnparsedDoc


class _PatchOnImport(MetaPathFinder):
    """Finds ``scipy._lib._array_api`` through the other finders and patches it right after it has run."""

    def find_spec(self, name, path=None, target=None):
        if name != _TARGET:
            return None
        if self in sys.meta_path:
            sys.meta_path.remove(self)  # once: the module is imported once
        spec = find_spec(name)
        loader = getattr(spec, "loader", None)
        if loader is None or not hasattr(loader, "exec_module"):
            return spec
        exec_module = loader.exec_module

        def exec_and_patch(module):
            exec_module(module)
            _patch(module)

        loader.exec_module = exec_and_patch
        return spec


if _TARGET in sys.modules:
    _patch(sys.modules[_TARGET])
elif not any(isinstance(f, _PatchOnImport) for f in sys.meta_path):
    sys.meta_path.insert(0, _PatchOnImport())
