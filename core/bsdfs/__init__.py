"""BSDF lobes: Lambert and GGX (bsdf.py, microfacet.py), their Fresnel terms
(fresnel.py), glass (glass.py), sheen (sheen.py) and the albedo tables of
layering and multiple scattering. Imports core.util and core.sampling."""
