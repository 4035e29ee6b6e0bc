"""
The ROS 2 face of the simulator: message conversions, parameters, QoS and the node.

Everything that knows about rclpy or message types lives in this package; it only converts
between messages and the physics core (:mod:`rigid_body_sim.physics`), which stays free of
ROS.  Importing this package imports nothing from ROS; import its modules.
"""
