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
- its compiled step on packed arrays (kernels/loop.py) and the two kernels built on it,
  ``run`` and ``controlled`` (the same step under error control).

Both forms compute the same method (tested to round-off); the Simulator runs the compiled
one, under every effect (kernels/model.py).  Adding an integrator: its module, decorated
with :func:`register_integrator`, and its import in ``integrators/__init__.py``.
"""

__all__ = ['INTEGRATORS', 'Integrator', 'register_integrator', 'get_integrator']

INTEGRATORS = {}
"""Integrator name -> :class:`Integrator` (callable as its readable step)."""


class Integrator:
    """
    A registered method: its name, order, readable step and compiled kernels.

    Calling it calls the readable step (see the module docstring).  ``run(state, model,
    method, dt, steps, time)`` and ``controlled(state, model, method, tick, ticks, time,
    control)`` are its kernels (kernels/loop.py, error_control.py); ``method`` is the tuple
    of its constants they take (a tuple, not an array: the compiler then knows them constant
    over the loop and hoists what it computes from them: 3.5 ns of Buss's 48 ns step).
    """

    def __init__(self, name, order, step, run, controlled, method=()):
        self.name = name
        self.order = order
        self.step = step
        self.run = run
        self.controlled = controlled
        self.method = tuple(float(value) for value in method)
        self.__doc__ = step.__doc__

    def __call__(self, body, state, time, dt, wrench):
        """Return the state after one readable step of dt s (see the module docstring)."""
        return self.step(body, state, time, dt, wrench)

    def __repr__(self):
        """Return ``Integrator('buss', order=2)``."""
        return f'Integrator({self.name!r}, order={self.order})'


def register_integrator(name, order, run, controlled, method=()):
    """
    Register the decorated readable step under `name`, with its order and kernels.

    run, controlled: the method's compiled kernels; method: its constants (passed to them).
    Returns the step unchanged; the registry holds an :class:`Integrator`.
    """
    def decorate(step):
        if name in INTEGRATORS:
            raise ValueError(f'integrator {name!r} is registered twice')
        INTEGRATORS[name] = Integrator(name, order, step, run, controlled, method)
        return step
    return decorate


def get_integrator(name):
    """Return the :class:`Integrator` registered as `name`; ValueError lists the valid names."""
    try:
        return INTEGRATORS[name]
    except (KeyError, TypeError):
        valid = ', '.join(sorted(INTEGRATORS))
        raise ValueError(f'unknown integrator {name!r}; valid integrators: {valid}') from None
