"""
Recording and analysis: rosbag2 bags of the simulation, offline or live, and their plots.

- :mod:`.bag_writer`: rosbag2 bags (MCAP or sqlite3), written by the package's own code
  through public APIs only: MCAP records built with the ``mcap`` library's record classes
  (Message and MessageIndex packed from the MCAP specification), sqlite3 through Python's
  :mod:`sqlite3`, ``metadata.yaml`` with PyYAML; from ``rosbags`` only its typestore
  (message definitions, type hashes) and QoS types.  The publishers' QoS profiles are
  stored as rosbag2 Jazzy records them, and the bag is readable at every flush (a recorder
  killed with SIGKILL leaves a readable bag).
- :mod:`.simulate`: a scene simulated faster than real time straight into a bag holding
  exactly the topics, types, frame ids and stamps the node publishes.
- :mod:`.recorder`: a live recorder for machines without rosbag2.
- :mod:`.recovery`: turn a bag left by a killed recorder into a complete one.
- :mod:`.motion`: the motion in a bag, read from the node's messages alone, and what its
  scene conserves; :mod:`.plot` plots it, :mod:`.animate` turns the body with it.

Importing this package imports none of them; import the module you need (the recorder
needs rclpy, the plot needs matplotlib).
"""
