"""``lazy_module(name)``: a module that is imported on the first access to one of its attributes.

For the heavy SciPy subpackages that a texture module uses in some functions only: ``skidsim.texture`` imports
every texture module, and the per-site MPD step then started ``scipy.ndimage`` and ``scipy.fft`` (about 0.25 s)
without calling them. The standard library's recipe (``importlib.util.LazyLoader``); a module that is already
imported is returned as it is.
"""

from __future__ import annotations

import importlib.util
import sys
from types import ModuleType


def lazy_module(name: str) -> ModuleType:
    """``name``'s module, executed on its first attribute access (its parent package is imported now)."""
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.find_spec(name)
    if spec is None or spec.loader is None:
        raise ModuleNotFoundError(f"No module named {name!r}", name=name)
    spec.loader = importlib.util.LazyLoader(spec.loader)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module
