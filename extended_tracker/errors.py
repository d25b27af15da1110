"""Exceptions of extended_tracker, raised at the edges with the bad value in the message."""

from __future__ import annotations


class ExtendedTrackerError(Exception):
    """Base class of every error this package raises on purpose."""


class ConfigError(ExtendedTrackerError, ValueError):
    """A configuration value is out of range, of the wrong type, or unknown."""


class ScanError(ExtendedTrackerError, ValueError):
    """A scan is malformed (inconsistent lengths, non-finite angles, ...)."""


class BagError(ExtendedTrackerError):
    """A bag cannot be read or written (missing, corrupt, no LaserScan topic, ...)."""


class PlotError(ExtendedTrackerError, ValueError):
    """A picture cannot be written where asked (a folder, an image format not known)."""
