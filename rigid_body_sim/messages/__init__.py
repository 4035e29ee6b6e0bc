"""
The message layer: what the node publishes and takes, as ROS 2 messages.

Everything that knows message types lives here, between the physics core and scenes below
and the node, the recording and the live view above, which all build their messages with
it: a bag written offline holds what the node publishes because both call these modules.

- :mod:`.state`: the state topics (pose, twist, angular_momentum, odom, marker) of a State,
  as messages or serialised bytes; :mod:`.marker`: how the body is drawn in them;
- :mod:`.wrench`: the torque and wrench inputs, validated;
- :mod:`.imu`: the ``imu`` topic's message;
- :mod:`.tf`: ``/tf`` and ``/tf_static``;
- :mod:`.diagnostics`: the contents of the ``/diagnostics`` status;
- :mod:`.qos`: the quality of service of every topic.

Importing this package imports nothing from ROS; import its modules.
"""
