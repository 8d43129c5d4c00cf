"""Shading: materials (the seed's response to a light, path mode's BSDFs), textures, optics, the
lights and path mode's emitters, and the environment."""
