"""rigid_body_sim: a rigid body simulated with geometric integrators, as a ROS 2 node."""

__version__ = '0.1.0'
