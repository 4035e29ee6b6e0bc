"""
The work-precision benchmarks behind ``rigid-body-sim bench``: what accuracy costs in CPU.

Three benchmarks share this library (the scripts in the checkout's ``benchmarks/`` folder
are one-off measurements, not part of it):

- torque-free bodies: :mod:`.bodies` (the bodies and initial states), :mod:`.reference`
  and :mod:`.extended_reference` (the reference orientations, committed in ``data/``),
  :mod:`.measure` (errors and CPU time of one run), :mod:`.report` (markdown, JSON/CSV and
  the work-precision plots);
- the tolerance sweep of error control on the built-in scenes: :mod:`.tolerance_sweep`,
  :mod:`.tolerance_report`;
- forced bodies: :mod:`.forces`, :mod:`.forces_report`;

and MuJoCo as their peer, an optional extra: :mod:`.peer_mujoco`.  Nothing here imports
rclpy.
"""
