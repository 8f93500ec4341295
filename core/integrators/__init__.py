"""Integrators by name."""
