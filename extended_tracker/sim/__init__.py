"""Simulators: point-cloud scenes for the filter core, ray-cast laser scans for the pipeline."""
