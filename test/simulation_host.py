"""
A stand-in host for the standard simulation services: a node of many bodies, kept small.

Until the node of many bodies (rigid_body_sim/node/world_node.py) serves them, the DDS tests
of :mod:`rigid_body_sim.node.simulation_services` run on this node: an rclpy Node over a
:class:`~rigid_body_sim.physics.World` with the host interface the services use (world,
scene, world_frame, stamp_nanoseconds, spawn_body, delete_body, set_body_state,
reset_simulation, playing, set_playing, step_while_paused, simulated_time), ticking at the
scene's rate while playing, its stamps the simulated time (as the node's with
publish_clock).  It publishes nothing: the tests read it through the services only.

Run as a script, spun as the node is (rclpy's EventsExecutor,
:func:`~rigid_body_sim.node.process.spin`)::

    python test/simulation_host.py --ros-args -r __ns:=/sim -p scene:=juggling_clubs
"""

import sys

import rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rigid_body_sim.node.process import spin
from rigid_body_sim.node.simulation_services import SimulationServices
from rigid_body_sim.scenes import load_scene

NODE_NAME = 'simulation_host'


class SimulationHost(Node):
    """The bodies of a scene in a World, ticking while playing; the services on top."""

    def __init__(self):
        super().__init__(NODE_NAME)
        self.scene = load_scene(self.declare_parameter('scene', 'juggling_clubs').value)
        self.world = self.scene.world()
        self.world_frame = 'world'
        self._playing = bool(self.declare_parameter('playing', True).value)
        self._initial = {member.name: member.state for member in self.scene.members}
        self._dt = self.scene.dt
        self.ticks_published = 0
        self._timer = self.create_timer(self._dt, self._tick)
        self.simulation_services = SimulationServices(self)

    def stamp_nanoseconds(self):
        """Return the stamp of the messages now: the simulated time in ns."""
        return round(self.world.time * 1e9)

    @property
    def simulated_time(self):
        """Get the simulated time in s."""
        return self.world.time

    @property
    def playing(self):
        """Get whether the bodies advance a tick at each tick of the timer."""
        return self._playing

    def set_playing(self, playing):
        """Play (True) or pause (False)."""
        self._playing = bool(playing)

    def spawn_body(self, name, member):
        """Add the one-body scene `member` as body `name` (ValueError: taken or invalid)."""
        if name in self.world:
            raise ValueError(f'a body called {name!r} exists already')
        self.world.add(name, member.simulator())
        self._initial[name] = member.state

    def delete_body(self, name):
        """Remove body `name` (KeyError if none)."""
        self.world.remove(name)
        del self._initial[name]

    def set_body_state(self, name, state):
        """Set the state (world frame) of body `name`."""
        self.world.set_state(name, state)

    def reset_simulation(self):
        """Put every body in its initial state, the simulated time at 0."""
        self.world.reset({name: self._initial[name] for name in self.world}, 0.0)

    def step_while_paused(self, ticks):
        """Advance exactly `ticks` ticks now (ValueError while playing)."""
        if self._playing:
            raise ValueError('playing: steps are taken while paused')
        for _ in range(ticks):
            self._step()

    def _tick(self):
        if self._playing:
            self._step()

    def _step(self):
        self.world.step(self._dt)
        self.ticks_published += 1


def main():
    """Serve until SIGINT or SIGTERM, spun as the node is (node/process.py's spin)."""
    rclpy.init(args=sys.argv, signal_handler_options=SignalHandlerOptions.NO)
    node = SimulationHost()
    node.get_logger().info('serving')
    try:
        spin(node)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
