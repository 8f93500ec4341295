"""The single list of render passes the engine writes (besides Combined)."""

# (name, channel count, channel ids, type) as register_pass takes them.
PASSES = (
    ("Depth", 1, "Z", "VALUE"),
    ("Normal", 3, "XYZ", "VECTOR"),
    ("Denoising Normal", 3, "XYZ", "VECTOR"),  # in camera space, as Cycles writes it
    ("Denoising Albedo", 3, "RGB", "COLOR"),
    ("ReSTIR Direct", 3, "RGB", "COLOR"),      # emission + direct light (ReSTIR modes)
    ("ReSTIR Indirect", 3, "RGB", "COLOR"),    # the reservoirs' indirect light (ReSTIR modes)
    ("ReSTIR Reservoir", 3, "XYZ", "VECTOR"),  # spatial reservoir M, W (debug)
)


# Combined before the denoiser, written when it is on (Cycles' name and layout).
NOISY = ("Noisy Image", 4, "RGBA", "COLOR")


def denoised(scene):
    """Whether final renders of the scene are denoised (ReSTIR GI modes)."""
    s = getattr(scene, "restir_gi", None)
    return s is not None and s.mode != "PATH" and bool(getattr(s, "use_denoising", False))


def register_passes(engine, scene, view_layer):
    engine.register_pass(scene, view_layer, "Combined", 4, "RGBA", "COLOR")
    for name, channels, chan_id, kind in PASSES:
        engine.register_pass(scene, view_layer, name, channels, chan_id, kind)
    if scene is not None and denoised(scene):
        engine.register_pass(scene, view_layer, *NOISY)
