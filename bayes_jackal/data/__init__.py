"""Data shipped with the package: the demo's simulated bags (``demo/``)."""
