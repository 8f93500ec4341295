"""BSDF lobes: Lambert and GGX (bsdf.py, microfacet.py), glass (glass.py), sheen
(sheen.py) and the albedo tables of multiple scattering. Imports core.util and
core.sampling."""
