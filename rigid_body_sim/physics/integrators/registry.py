"""
The integrator registry: one name -> one method, in a readable and a compiled form.

Each method is one module (buss.py, rk4.py, ...) holding

- its readable step, a pure function on the immutable State,

      step(body, state, time, dt, wrench) -> State

  body : RigidBody; state : State (world frame) at `time` (s); dt : step in s; wrench :
  None for torque-free motion, or a callable ``wrench(state, time) -> (force, torque)``
  giving the total external force through the COM (N) and torque about it (N m), world
  frame; a wrench that depends on the momenta (drag) carries ``momentum_dependent = True``
  so that the method keeps its order for it;
- its compiled step on packed arrays (kernels/loop.py) and the run kernel built on it
  (error control drives any run kernel: error_control.controlled).

Both forms compute the same method (tested to round-off); the Simulator runs the compiled
one, under every effect (kernels/model.py).  Adding an integrator: its module, decorated
with :func:`register_integrator`, and its import in ``integrators/__init__.py``.
"""

from ..kernels.loop import method_constants

__all__ = ['INTEGRATORS', 'Integrator', 'register_integrator', 'get_integrator']

INTEGRATORS = {}
"""Integrator name -> :class:`Integrator` (callable as its readable step)."""


class Integrator:
    """
    A registered method: its name, order, readable step and compiled kernel.

    Calling it calls the readable step (see the module docstring).  ``run_kernel`` is its
    run kernel (a :class:`~..kernels.LazyKernel` of kernels/loop.py's RUN_SIGNATURE: several
    methods may share one, with different constants); ``run`` the compiled function
    (compiled or loaded on first use); ``method`` the tuple of constants it takes.
    """

    def __init__(self, name, order, step, run, method=()):
        self.name = name
        self.order = order
        self.step = step
        self.run_kernel = run
        self.method = method_constants(method)
        self.__doc__ = step.__doc__

    @property
    def run(self):
        """Get the compiled run kernel (compiled, or loaded from the cache, on first use)."""
        return self.run_kernel.dispatcher

    def __call__(self, body, state, time, dt, wrench):
        """Return the state after one readable step of dt s (see the module docstring)."""
        return self.step(body, state, time, dt, wrench)

    def __repr__(self):
        """Return ``Integrator('buss', order=2)``."""
        return f'Integrator({self.name!r}, order={self.order})'


def register_integrator(name, order, run, method=()):
    """
    Register the decorated readable step under `name`, with its order and run kernel.

    run: the method's run kernel (kernels/loop.run_kernel); method: its constants (passed
    to it, at most kernels/loop.METHOD_SIZE).  Returns the step unchanged; the registry
    holds an :class:`Integrator`.
    """
    def decorate(step):
        if name in INTEGRATORS:
            raise ValueError(f'integrator {name!r} is registered twice')
        INTEGRATORS[name] = Integrator(name, order, step, run, method)
        return step
    return decorate


def get_integrator(name):
    """Return the :class:`Integrator` registered as `name`; ValueError lists the valid names."""
    try:
        return INTEGRATORS[name]
    except (KeyError, TypeError):
        valid = ', '.join(sorted(INTEGRATORS))
        raise ValueError(f'unknown integrator {name!r}; valid integrators: {valid}') from None
