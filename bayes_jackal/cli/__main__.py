"""``python -m bayes_jackal.cli``: the same command line as ``bayes-jackal``."""

from . import console

console()
