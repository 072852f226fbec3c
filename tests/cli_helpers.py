"""What the tests of the command line share (imported as tests/synthetic_posteriors.py is).

``CLI`` runs ``bayes-jackal`` as a subprocess of this interpreter;
:func:`strict_json` parses its JSON as every parser but Python's would.
"""

from __future__ import annotations

import json
import sys

#: ``bayes-jackal`` as a subprocess (the module form; the venv's interpreter).
CLI = [sys.executable, "-m", "bayes_jackal.cli"]


def strict_json(text: str) -> object:
    """Parse JSON refusing NaN and Infinity (which json.loads accepts by default)."""

    def refuse(name: str):
        raise ValueError(f"not valid JSON: {name}")

    return json.loads(text, parse_constant=refuse)
