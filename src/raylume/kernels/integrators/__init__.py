"""Integrators: the lanes and per-row loops (frame.py), cast and Whitted tracing ray by ray
(trace.py, direct.py) and as a wavefront (wavefront.py), and the path tracer (path.py)."""
