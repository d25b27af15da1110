"""Install extended_tracker as an ament_python package (colcon) or with pip (venv)."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'extended_tracker'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(include=[package_name, package_name + '.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/config/mounts', glob('config/mounts/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
        ('share/' + package_name + '/rviz', glob('rviz/*.rviz')),
    ],
    package_data={package_name: ['py.typed']},
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='extended_tracker maintainers',
    maintainer_email='maintainers@extended-tracker.invalid',
    description='GGIW-CPHD multiple extended object tracking for 2D laser scans',
    license='BSD-3-Clause',
    python_requires='>=3.10',
    entry_points={
        'console_scripts': [
            'tracker_node = extended_tracker.ros.entry:main',
            'extended-tracker = extended_tracker.cli:main',
        ],
    },
)
