"""Force laws written in Python: :class:`PythonForce`.

A :class:`PythonForce` is a callable ``force(t, q, qd)`` on the coordinates
of named bodies (``x, y, phi`` of each, in the order named), returning the
generalized forces on them (``fx`` [N], ``fy`` [N], torque about the body's
reference point [N m] per body). The library adds it to the system as one
more force element (``mbsolve::forces::CallbackForce``): it is called once
per evaluation of the forces (each right-hand side or residual, the
stages and rejected steps of a method included), with the GIL taken for
the call while the rest of the run goes on without it.

Jacobians (implicit methods only): ``jacobian(t, q, qd)`` returning
``(dg_dq, dg_dqd)``, two k × k arrays (k = 3 × bodies), or, without one,
central finite differences of ``force`` (4k more calls per Jacobian).

State: ``force`` may keep state, but it sees trial states (stages,
rejected steps, difference quotients), so state that must follow the
accepted solution (a PID's integral, a filter) belongs in ``step(t, q,
qd)``, called once after each accepted step; ``force`` then reads it.

An exception in ``force``, ``jacobian`` or ``step`` ends the run: its
:class:`mbsolve.Result` has status ``"failed"`` (``"interrupted"`` for a
``KeyboardInterrupt``), ``message`` names the force, the exception and the
time, ``exception`` holds the exception itself, and the rows computed
before it are kept.
"""

from __future__ import annotations

from typing import Any, Callable, List, Optional, Sequence, Tuple, Union

import numpy as np

ForceFn = Callable[[float, np.ndarray, np.ndarray], Any]
JacobianFn = Callable[[float, np.ndarray, np.ndarray], Tuple[Any, Any]]
StepFn = Callable[[float, np.ndarray, np.ndarray], Any]


class PythonForce:
    """A force law in Python on the bodies ``bodies`` (names as in the
    scenario). ``force(t, q, qd)`` gets ``t`` [s] and ``q``, ``qd`` as
    float64 arrays of length k = 3 × len(bodies) (``x, y, phi`` of each body
    in the order named; m, rad and m/s, rad/s) and returns k generalized
    forces (N, N, N m per body, global axes, torque about the body's
    reference point). Optional: ``jacobian(t, q, qd) -> (dg_dq, dg_dqd)``
    (k × k each, ``[r][c] = ∂g_r/∂q_c``; default: central finite
    differences) and ``step(t, q, qd)`` called after each accepted step
    (for state that follows the accepted solution).

    Pass it to :meth:`mbsolve.Scenario.run` (``forces=[...]``),
    :meth:`mbsolve.Scenario.with_forces` or :meth:`mbsolve.Model.python_force`.
    """

    __slots__ = ("name", "bodies", "force", "jacobian", "step")

    def __init__(self, name: str, bodies: Union[str, Sequence[str]], force: ForceFn, *,
                 jacobian: Optional[JacobianFn] = None, step: Optional[StepFn] = None) -> None:
        if isinstance(bodies, str):
            bodies = [bodies]
        bodies = [str(b) for b in bodies]
        if not bodies:
            raise ValueError(f"python force '{name}': bodies: name at least one body")
        for what, f in (("force", force), ("jacobian", jacobian), ("step", step)):
            if f is not None and not callable(f):
                raise TypeError(f"python force '{name}': {what} must be callable, "
                                f"not {type(f).__name__}")
        #: Name used in messages.
        self.name: str = str(name)
        #: The bodies whose coordinates the law reads and loads, in order.
        self.bodies: List[str] = bodies
        #: ``force(t, q, qd)`` -> k generalized forces.
        self.force: ForceFn = force
        #: ``jacobian(t, q, qd)`` -> ``(dg_dq, dg_dqd)`` or None.
        self.jacobian: Optional[JacobianFn] = jacobian
        #: ``step(t, q, qd)`` after each accepted step, or None.
        self.step: Optional[StepFn] = step

    @property
    def size(self) -> int:
        """k = 3 × number of bodies: the length of ``q``, ``qd`` and ``g``."""
        return 3 * len(self.bodies)

    def _spec(self) -> Tuple[str, List[str], Callable, Optional[Callable], Optional[Callable]]:
        """What the extension takes: name, bodies and adapters that turn its
        lists into arrays and check what the user's functions return."""
        k, name = self.size, self.name
        force, jacobian, step = self.force, self.jacobian, self.step
        array, asarray = np.array, np.asarray

        def shaped(v: Any, shape: Tuple[int, ...], what: str) -> np.ndarray:
            a = asarray(v, dtype=np.float64)
            if a.shape != shape:
                if a.size == int(np.prod(shape)) and a.ndim <= 1 and len(shape) == 1:
                    return a.reshape(shape)
                raise ValueError(f"python force '{name}': {what} returned shape {a.shape}, "
                                 f"expected {shape} (3 values per body: "
                                 f"{', '.join(self.bodies)})")
            return a

        def call_force(t: float, q: list, qd: list) -> list:
            return shaped(force(t, array(q), array(qd)), (k,), "force").tolist()

        call_jacobian = None
        if jacobian is not None:
            def call_jacobian(t: float, q: list, qd: list) -> list:
                out = jacobian(t, array(q), array(qd))
                if not isinstance(out, (tuple, list)) or len(out) != 2:
                    raise ValueError(f"python force '{name}': jacobian must return "
                                     "(dg_dq, dg_dqd)")
                a = shaped(out[0], (k, k), "jacobian (dg_dq)")
                b = shaped(out[1], (k, k), "jacobian (dg_dqd)")
                return a.ravel().tolist() + b.ravel().tolist()

        call_step = None
        if step is not None:
            def call_step(t: float, q: list, qd: list) -> None:
                step(t, array(q), array(qd))

        return (name, list(self.bodies), call_force, call_jacobian, call_step)

    def __repr__(self) -> str:
        extra = "".join(f", {w}=..." for w in ("jacobian", "step") if getattr(self, w))
        return f"PythonForce({self.name!r}, bodies={self.bodies!r}{extra})"
