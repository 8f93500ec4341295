"""Path tracing: bounces (bounces.py), shadow rays and the render context
(base.py), surfaces rays pass through (transparency.py), and the path tracer
(path.py). Imports every layer below it, not core.restir."""
