"""
Stiff effects: how fast an effect can damp the motion before a method's step cannot follow.

An effect that damps the momenta linearly (drag: dp/dt = -(c1/m) p, dL/dt = -k1 omega) makes
the test equation y' = -lambda y of every explicit method: a step h is stable only while
lambda h stays within the method's limit, and beyond it the state grows without bound and
turns non-finite in a few steps (issue 22: `drag: {rotational_linear: 10}` on a 0.4 x 0.2 x
0.1 m box decays at 2000 /s, lambda h = 20 at 100 Hz, and buss went NaN).

The limit of each integrator is measured on its own compiled kernel, not tabled by hand
(:func:`decay_limit`): a sphere under linear rotational drag, L shrinking by the method's
amplification factor g(lambda h) per step; the limit is the first lambda h at which |g|
exceeds 1.  A new integrator gets its limit without an edit here.  The theory follows from
the registration (test/test_stiff_and_divergent.py checks each measured limit against it):
an explicit method of order p <= 4 with p stages has the truncated exponential as its
amplification factor (Euler 2, classical RK4 2.785); a kick-drift-kick stage of c h has
g(c z) = (1 - c z/2)(1 - c z/2 + c^2 z^2/4) (two kicks of c h/2, the second started from the
first's estimate: kernels/model.py's impulse), 3.087 for one stage, and a composition of
stages the product of theirs.

Effects say how stiff they are (``damping_rate(body) -> (rate 1/s, what)``, registry.py); the
Simulator checks each new step against them (:func:`stiffness_problem`).
"""

from __future__ import annotations

from collections.abc import Iterable
from collections.abc import Sequence
import functools
import math
from typing import Protocol

import numpy as np

from .body import RigidBody
from .effects import Drag
from .effects.registry import Effect
from .integrators import get_integrator
from .kernels import interpreting
from .kernels.layout import body_values
from .kernels.layout import STATE_SIZE
from .kernels.model import new_model

__all__ = ['decay_limit', 'stiffness_problem', 'step_problem', 'LIMIT_MARGIN', 'Configured']

LIMIT_MARGIN = 0.9
"""The fraction of a method's limit a step may use (the limit itself is neutral, |g| = 1)."""


class Configured(Protocol):
    """What :func:`stiffness_problem` reads of a simulator (a Simulator has each)."""

    @property
    def body(self) -> RigidBody:
        """Get the body simulated."""

    @property
    def effects(self) -> Sequence[Effect]:
        """Get the effects on it."""

    @property
    def integrator(self) -> str:
        """Get the registered name of its integrator."""

    @property
    def substeps(self) -> int:
        """Get its steps per tick (the fixed count, or the lower bound under error control)."""


_SCAN = np.arange(0.02, 20.0, 0.02)


@functools.lru_cache(maxsize=None)
def decay_limit(integrator: str) -> float:
    """
    Return the largest lambda h (dimensionless) at which `integrator` damps y' = -lambda y.

    Measured on the integrator's run kernel (compiled, or its source while interpreting): a
    unit sphere (I = 1 kg m^2) turning at 1 rad/s under linear rotational drag k1 = 1 N m s
    (lambda = 1/s), one step of h from the same state for each h of a scan; the first h at
    which |L| grows ends the stable range.
    """
    method = get_integrator(integrator)
    body = RigidBody(1.0, (1.0, 1.0, 1.0))
    drag = Drag(rotational_linear=1.0)
    model = new_model(body_values(body.inertia, body.inertia_inverse, body.mass),
                      np.zeros((4, 3)),
                      terms=[(drag.compiled_wrench, drag.wrench_parameters(body))],
                      momentum_dependent=drag.momentum_dependent,
                      reads_state=drag.reads_state, interpreted=interpreting())
    # At rest at the origin, unturned (q = (0, 0, 0, 1)), L = (0, 0, 1) kg m^2/s.
    start = np.zeros(STATE_SIZE)
    start[3] = start[12] = 1.0
    previous = 0.0
    for h in _SCAN:
        values = start.copy()
        method.run_kernel(values, model, method.method, float(h), 1, 0.0)
        if not abs(values[12]) <= 1.0:
            return float(previous)
        previous = float(h)
    return float(previous)


def stiffness_problem(simulator: Configured, dt: float) -> tuple[float, str] | None:
    """
    Return (substeps needed, message) if a step of dt s is too long for an effect, else None.

    The step taken is dt / substeps (the simulator's fixed count, or its lower bound under
    error control).  The message names the effect, its rate and what to change.
    """
    return step_problem(simulator.body, simulator.effects, simulator.integrator,
                        simulator.substeps, dt)


def step_problem(body: RigidBody, effects: Iterable[Effect], integrator: str, substeps: int,
                 dt: float) -> tuple[float, str] | None:
    """
    Return (substeps needed, message) if dt / substeps s is too long a step, else None.

    As :func:`stiffness_problem`, for a configuration not (yet) a simulator's: `body` and
    `effects` as a Simulator holds them, `integrator` a registered name, dt in s.
    """
    steps = substeps
    h = dt / steps
    for effect in effects:
        damping_rate = getattr(effect, 'damping_rate', None)
        if damping_rate is None:
            continue
        rate, what = damping_rate(body)
        if not rate > 0.0:
            continue
        # Measured on the integrator's kernel: only where an effect damps at all.
        limit = LIMIT_MARGIN * decay_limit(integrator)
        if not rate * h > limit:
            continue
        if limit <= 0.0:
            return math.inf, (f'{effect.effect_name} damps the motion at {rate:.4g} /s '
                              f'({what}), which {integrator} cannot follow at any '
                              'step; choose another integrator')
        needed = math.ceil(rate * dt / limit)
        return needed, (
            f'{effect.effect_name} damps the motion at {rate:.4g} /s ({what}): a step of '
            f'{h:.3g} s is unstable for {integrator}, which follows a decay up to '
            f'{limit / h:.4g} /s at it; raise rate to at least '
            f'{rate / (steps * limit):.4g} Hz or substeps to {needed}, or lower the '
            'coefficient')
    return None
