"""
The work-precision benchmark behind ``rigid-body-sim bench``.

Modules, in data-flow order: :mod:`.bodies` (the benchmark bodies and initial states),
:mod:`.reference` (the reference orientations), :mod:`.peer_mujoco` (the same bodies in
MuJoCo, an optional extra), :mod:`.measure` (errors and CPU time of one run), and
:mod:`.report` (markdown, JSON/CSV and the work-precision plot).  Nothing here imports rclpy.
"""
