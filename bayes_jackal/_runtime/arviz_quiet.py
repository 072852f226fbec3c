"""arviz, imported once with its announcement of the 1.x refactor silenced.

arviz 0.2x warns on import that 1.x will replace InferenceData; the package
pins ``arviz<1`` (docs/design.md §4). Every module takes ``az`` from here.
"""

import warnings

with warnings.catch_warnings():
    warnings.simplefilter("ignore", FutureWarning)
    import arviz as az

__all__ = ["az"]
