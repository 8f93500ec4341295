"""Helpers on rows of (N, k) arrays (rows.py), row-wise vectors (vectors.py) and
error notes (errors.py): the bottom of core, importing nothing else from it."""
