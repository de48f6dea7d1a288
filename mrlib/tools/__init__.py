"""Checks of the package itself (``python -m mrlib.tools.layers``)."""
