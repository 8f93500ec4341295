"""The rendered viewport: the session and its render thread (session.py), its
progressive refinement (progress.py), and the engine's callbacks with the GPU
drawing (draw.py). Imports core, restir_addon.sync and restir_addon.final."""
