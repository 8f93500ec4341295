"""The single list of render passes the engine writes (besides Combined)."""

# (name, channel count, channel ids, type) as register_pass takes them.
PASSES = (
    ("Depth", 1, "Z", "VALUE"),
    ("Normal", 3, "XYZ", "VECTOR"),
    ("Denoising Albedo", 3, "RGB", "COLOR"),
    ("ReSTIR Direct", 3, "RGB", "COLOR"),      # emission + direct light (ReSTIR modes)
    ("ReSTIR Indirect", 3, "RGB", "COLOR"),    # the reservoirs' indirect light (ReSTIR modes)
    ("ReSTIR Reservoir", 3, "XYZ", "VECTOR"),  # spatial reservoir M, W (debug)
)


def register_passes(engine, scene, view_layer):
    engine.register_pass(scene, view_layer, "Combined", 4, "RGBA", "COLOR")
    for name, channels, chan_id, kind in PASSES:
        engine.register_pass(scene, view_layer, name, channels, chan_id, kind)
