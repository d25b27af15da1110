"""Laser front end: scan conversion, scan-shadow p_D, static background."""
