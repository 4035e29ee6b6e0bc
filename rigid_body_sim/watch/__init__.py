"""
``rigid-body-sim watch``: a live view of a running rigid_body_node, without a ROS install.

live.py holds what is known of the node (plain numbers, no rclpy); listener.py finds the
node over DDS and feeds it; terminal.py and window.py show it.
"""
