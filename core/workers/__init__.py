"""Whole-image passes over pixel ranges on two workers: threads, or a forked
twin process (forked.py). Imports core.util."""
