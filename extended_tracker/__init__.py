"""Multiple extended object tracking in 2D laser scans (GGIW-CPHD) for ROS 2."""

__version__ = '0.1.0'   # as in package.xml and setup.py (test/test_package_manifest.py)
