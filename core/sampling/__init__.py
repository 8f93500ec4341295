"""Random streams per pixel (samplers.py) and warps from the unit square with
their densities (warps.py). Imports core.util."""
