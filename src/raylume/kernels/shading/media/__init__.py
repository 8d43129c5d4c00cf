"""Participating media (DESIGN.md section 7): one module per kind (homogeneous.py, grid.py), each
its row of the medium table packed from the model and its coefficients at a point; table.py the
table's columns; phase.py the Henyey-Greenstein phase function; tracking.py free-flight
sampling and transmittance along a ray, the same for every kind over a piecewise-constant
majorant; boundaries.py which medium lies on each side of an object. Path mode renders them
(both integrators); the other modes show the boundaries' materials alone."""

from .boundaries import medium_beyond, medium_leaving
from .phase import hg_eval, hg_sample
from .table import MED_G, MED_WIDTH
from .tracking import free_flight, transmittance

__all__ = [
    "MED_G",
    "MED_WIDTH",
    "free_flight",
    "hg_eval",
    "hg_sample",
    "medium_beyond",
    "medium_leaving",
    "transmittance",
]
