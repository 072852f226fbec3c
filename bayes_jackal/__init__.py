"""bayes_jackal: Bayesian system identification of skid-steer mobile robots.

The public names are imported on first use (PEP 562), so that importing the
package, e.g. for ``bayes-jackal --version``, does not load numpy and scipy.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

#: Public name -> the module that defines it.
_LAZY = {
    "DataError": ".errors",
    "InputError": ".errors",
    "OutputError": ".errors",
    "ProfileError": ".errors",
    "RobotProfile": ".robot",
    "load_profile": ".robot",
}

__all__ = [
    "DataError",
    "InputError",
    "OutputError",
    "ProfileError",
    "RobotProfile",
    "__version__",
    "load_profile",
]


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(_LAZY[name], __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
