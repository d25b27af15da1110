"""Metrics, the scenario suite and its results table, the benchmark."""
