"""Planar poses, the transforms between frames, and the filter's state moved between them."""
