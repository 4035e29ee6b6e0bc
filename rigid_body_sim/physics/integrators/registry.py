"""
The integrator registry: one name -> one method, with everything a tool or a test asks of it.

Each method is one module (buss.py, rk4.py, ...) holding its compiled step on packed arrays
(kernels/loop.py) and the run kernel built on it; error control drives any run kernel
(error_control.controlled).  The module registers each method it defines with
:func:`register_integrator`: its order, where its step takes the wrench, what its torque-free
step conserves exactly, and its run kernel (with that kernel's compile estimate).  Tools,
tests, the warm-up and the docs' table read these declarations here rather than keeping lists
of names; the tests check each declaration against what the kernel does.

Adding an integrator: its module, calling :func:`register_integrator`, and its import in
``integrators/__init__.py``.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from ..kernels import LazyKernel
from ..kernels.loop import method_constants

__all__ = ['INTEGRATORS', 'Integrator', 'register_integrator', 'get_integrator',
           'CONSERVED_QUANTITIES', 'KICK_STAGE']

INTEGRATORS: dict[str, Integrator] = {}
"""Integrator name -> :class:`Integrator`, in the order of registration."""

CONSERVED_QUANTITIES = ('angular_momentum', 'rotational_energy')
"""What a torque-free step may conserve exactly: world L (bit for bit, hence |L| too), and
the rotational kinetic energy (to round-off)."""

KICK_STAGE = (1.0,)
"""The one kick-drift-kick stage of a Strang step: kick(h/2), drift(h), kick(h/2)."""


class Integrator:
    """
    A registered method: what it is, where it takes the wrench, what it conserves.

    Attributes
    ----------
    name : str
        Its registered name.
    order : int
        Its order of convergence (an error O(h^order) over a fixed span) torque-free and with
        any wrench of the configuration and time.
    momentum_dependent_order : int
        Its order with a wrench that depends on the momenta (drag), which a kicking method
        takes by the kicks' explicit midpoint rule, second order (kernels/model.py's
        impulse).
    summary : str
        One line on what it is (the docs' table).
    kicks : tuple of float
        The coefficients c_i of its kick-drift-kick stages, kick(c_i h/2) drift(c_i h)
        kick(c_i h/2), in order (the time runs with them); () if the wrench does not enter
        as kicks around a torque-free drift.
    wrench_samples : tuple of (float, float)
        Where in a step of h it evaluates the wrench, as (fraction of h, weight) pairs in
        order: its quadrature of a wrench that depends on the time alone, which changes
        L by h sum(weight tau(t + fraction h)).  Derived from `kicks` for a kicking method.
    stages : int
        Wrench evaluations per step (len(wrench_samples)); a momentum-dependent wrench adds
        one per kick stage (the opening kick's midpoint rule: kernels/model.py's impulse).
    conserves : tuple of str
        Which of :data:`CONSERVED_QUANTITIES` its torque-free step keeps exactly.
    exact_torque_free : bool
        Torque-free, the step is the exact flow: its error is round-off at any step.
    run_kernel : LazyKernel
        Its run kernel (kernels/loop.py's RUN_SIGNATURE; several methods may share one, with
        different constants); ``run`` the compiled function, compiled or loaded on first use.
    method : tuple of float
        The constants it passes its run kernel (padded to kernels/loop.METHOD_SIZE).
    compile_job : str
        The compile job of its run kernel: ``run-<module>`` (physics/warm_up.py).
    compile_seconds : float
        That job's estimated CPU seconds to compile, declared with the run kernel.

    """

    def __init__(self, name: str, order: int, run: LazyKernel, method: Iterable[float] = (),
                 summary: str = '', kicks: Iterable[float] = (),
                 wrench_samples: Iterable[tuple[float, float]] | None = None,
                 conserves: Iterable[str] = (), exact_torque_free: bool = False,
                 momentum_dependent_order: int | None = None) -> None:
        unknown = set(conserves) - set(CONSERVED_QUANTITIES)
        if unknown:
            raise ValueError(f'integrator {name!r}: unknown conserved quantities {unknown}; '
                             f'valid: {", ".join(CONSERVED_QUANTITIES)}')
        kicks = tuple(float(c) for c in kicks)
        if kicks:
            if wrench_samples is not None:
                raise ValueError(f'integrator {name!r}: the wrench samples of a kicking method '
                                 'follow from its kicks; give one of them')
            wrench_samples = _kick_samples(kicks)
        if not wrench_samples:
            raise ValueError(f'integrator {name!r}: say where its step takes the wrench '
                             '(kicks or wrench_samples)')
        self.name = name
        self.order = int(order)
        self.momentum_dependent_order = int(order if momentum_dependent_order is None
                                            else momentum_dependent_order)
        self.summary = summary
        self.kicks = kicks
        self.wrench_samples = tuple((float(t), float(w)) for t, w in wrench_samples)
        self.stages = len(self.wrench_samples)
        self.conserves = tuple(conserves)
        self.exact_torque_free = bool(exact_torque_free)
        self.run_kernel = run
        self.method = method_constants(method)

    @property
    def run(self) -> Any:
        """Get the compiled run kernel (compiled, or loaded from the cache, on first use)."""
        return self.run_kernel.dispatcher

    @property
    def compile_job(self) -> str:
        """Get the compile job of its run kernel: ``run-<the module that declares it>``."""
        return 'run-' + self.run_kernel.__module__.rsplit('.', 1)[-1]

    @property
    def compile_seconds(self) -> float | None:
        """Get the CPU seconds its run kernel takes to compile, as declared with it."""
        return self.run_kernel.compile_seconds

    def __repr__(self) -> str:
        """Return ``Integrator('buss', order=2)``."""
        return f'Integrator({self.name!r}, order={self.order})'


def _kick_samples(kicks: Iterable[float]) -> tuple[tuple[float, float], ...]:
    """Return the wrench samples of kick-drift-kick stages c_i: each kick at its stage's end."""
    samples, start = [], 0.0
    for c in kicks:
        samples += [(start, 0.5 * c), (start + c, 0.5 * c)]
        start += c
    return tuple(samples)


def register_integrator(name: str, order: int, run: LazyKernel, method: Iterable[float] = (),
                        summary: str = '', kicks: Iterable[float] = (),
                        wrench_samples: Iterable[tuple[float, float]] | None = None,
                        conserves: Iterable[str] = (), exact_torque_free: bool = False,
                        momentum_dependent_order: int | None = None) -> Integrator:
    """
    Register the method `name` (see :class:`Integrator` for the arguments) and return it.

    run: its run kernel (kernels/loop.run_kernel, which declares the compile estimate);
    method: its constants (passed to the kernel, at most kernels/loop.METHOD_SIZE);
    momentum_dependent_order: default `order`.
    """
    if name in INTEGRATORS:
        raise ValueError(f'integrator {name!r} is registered twice')
    integrator = Integrator(name, order, run, method, summary, kicks, wrench_samples,
                            conserves, exact_torque_free, momentum_dependent_order)
    INTEGRATORS[name] = integrator
    return integrator


def get_integrator(name: str) -> Integrator:
    """Return the :class:`Integrator` registered as `name`; ValueError lists the valid names."""
    try:
        return INTEGRATORS[name]
    except (KeyError, TypeError):
        valid = ', '.join(sorted(INTEGRATORS))
        raise ValueError(f'unknown integrator {name!r}; valid integrators: {valid}') from None
