"""
The ROS 2 node ``rigid_body_node``: the simulation run live, on a timer, over DDS.

- :mod:`.rigid_body_node`: the node (its ticks, inputs, services and reports);
- :mod:`.world_node`: the node of a scene of several bodies (one World, each body's topics
  and frames under its name), which the executable starts for such a scene;
- :mod:`.parameters` and :mod:`.parameter_services`: its parameters, their checks and
  the services that set them;
- :mod:`.process`: its process (start-up, signals, spin), started by :mod:`.entry_point`
  (the ``rigid_body_node`` executable) with its ``--help`` from :mod:`.help_text`;
- :mod:`.background_compile`: kernels not compiled yet, compiled in a process beside it.
- :mod:`.simulation_services`: ROS 2's standard simulation services (simulation_interfaces)
  on a node of many bodies.

It sits on top of the message layer (:mod:`rigid_body_sim.messages`), the scenes and the
physics core, and nothing in the package imports it.  Importing this package imports
nothing from ROS; import its modules.
"""
