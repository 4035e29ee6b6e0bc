"""
The integrator registry: one name -> one step function with one shared signature.

Every integrator is a pure function

    step(body, state, time, dt, wrench) -> State

body : RigidBody (fixed mass properties); state : State (world frame) at `time` (s);
dt : step in s; wrench : None for torque-free motion, or a callable
``wrench(state, time) -> (force, torque)`` giving the total external force through the COM
(N) and torque about the COM (N m), both in the world frame.  A wrench whose value depends on
the momenta (drag) carries the attribute ``momentum_dependent = True`` so that methods can
keep their order for it.

Registering takes the method's order of accuracy and, optionally, a fast path: a
:class:`~rigid_body_sim.physics.integrators.fast.CompiledIntegrator`, whose ``run``
advances a packed state in place over `steps` steps under a held wrench (fixed in the world
or in the body, and a world force at a body point), with a dissipation flow fused in.  The
fast path must equal the readable step to round-off (tested).
"""

INTEGRATORS = {}
"""Integrator name -> step function (see the module docstring for the signature)."""

FAST_KERNELS = {}
"""Integrator name -> compiled multi-step kernel, for integrators that have one."""


def register_integrator(name, order, fast_kernel=None):
    """
    Register the decorated step function under `name`, with its order of accuracy.

    The function gains the attributes ``integrator_name`` and ``order``.  `fast_kernel`, if
    given, must be a CompiledIntegrator (TypeError otherwise).
    """
    from .fast import CompiledIntegrator
    if fast_kernel is not None and not isinstance(fast_kernel, CompiledIntegrator):
        raise TypeError(f'the fast path of integrator {name!r} must be a CompiledIntegrator '
                        f'(integrators/fast.py); got {type(fast_kernel).__name__}')

    def decorate(step):
        if name in INTEGRATORS:
            raise ValueError(f'integrator {name!r} is registered twice')
        step.integrator_name = name
        step.order = order
        INTEGRATORS[name] = step
        if fast_kernel is not None:
            FAST_KERNELS[name] = fast_kernel
        return step
    return decorate


def get_integrator(name):
    """Return the step function registered as `name`; ValueError lists the valid names."""
    try:
        return INTEGRATORS[name]
    except (KeyError, TypeError):
        valid = ', '.join(sorted(INTEGRATORS))
        raise ValueError(f'unknown integrator {name!r}; valid integrators: {valid}') from None
