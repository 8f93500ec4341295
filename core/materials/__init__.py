"""Materials: shader node graphs (shader/), image textures (texture.py), and the
BSDF parameters and emission of hits (shading.py). Imports the layers below
it: core.util, core.workers, core.sampling, core.geometry, core.camera,
core.bsdfs."""
