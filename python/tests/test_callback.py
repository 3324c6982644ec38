"""Python in the loop: a force law written in Python (PythonForce) against
the same law as an `expression` force, exceptions that end a run with its
rows kept, step hooks for controller state, bad input."""

import math

import numpy as np
import pytest

import mbsolve

LAW = "-2*bob.phi - 0.1*bob.omega + 0.3*sin(3*t)"


def law(t, q, qd):
    """LAW on the bob's (x, y, phi): only a torque."""
    return [0.0, 0.0, -2.0 * q[2] - 0.1 * qd[2] + 0.3 * math.sin(3.0 * t)]


def law_jacobian(t, q, qd):
    dq = np.zeros((3, 3))
    dqd = np.zeros((3, 3))
    dq[2, 2] = -2.0
    dqd[2, 2] = -0.1
    return dq, dqd


def pendulum(method, expression=False, end=1.0):
    """A bob on a revolute at the origin (l = 0.5 m) under gravity."""
    m = mbsolve.Model("pendulum", gravity=(0.0, -9.81))
    m.body("bob", mass=1.0, inertia=0.02, x=0.5, y=0.0, phi=0.0)
    m.joint("revolute", body_i="ground", point_i=[0.0, 0.0], body_j="bob",
            point_j=[-0.5, 0.0])
    if expression:
        m.force("expression", name="law", body="bob", torque=LAW)
    extra = {"genalpha": {"step": 1e-3}, "radau5": {"adaptive": True}}.get(method, {})
    m.integrator(method=method, **extra)
    m.time(end=end).output(dt=0.01)
    return m


@pytest.mark.parametrize("method,jacobian", [("ode45", None), ("genalpha", None),
                                             ("bdf", None), ("radau5", law_jacobian)])
def test_python_force_equals_expression_force(method, jacobian):
    ref = pendulum(method, expression=True).run()
    m = pendulum(method)
    calls = []

    def counted(t, q, qd):
        calls.append(t)
        return law(t, q, qd)

    m.python_force("law", ["bob"], counted, jacobian=jacobian)
    r = m.run()
    assert ref.status == r.status == "completed"
    assert np.array_equal(ref.t, r.t)
    # the same law: the explicit run and the run with the law's own
    # Jacobian agree to rounding; finite-difference Jacobians change the
    # Newton iterates within the Newton tolerance
    tol = 1e-12 if method in ("ode45", "radau5") else 1e-8
    for c in ("bob.x", "bob.y", "bob.phi"):
        assert np.max(np.abs(ref[c] - r[c])) < tol, (c, np.max(np.abs(ref[c] - r[c])))
    assert np.max(np.abs(ref["bob.phi"])) > 0.5  # it swings: the comparison means something
    # called at every evaluation of the forces: at least once per RHS
    assert len(calls) >= r.summary["rhs_evals"] > 0


def test_exception_ends_the_run_as_failed_with_its_rows():
    full = pendulum("ode45").run(forces=[mbsolve.PythonForce("law", "bob", law)])

    def failing(t, q, qd):
        if t > 0.5:
            raise ValueError("controller saturated")
        return law(t, q, qd)

    r = pendulum("ode45").run(forces=[mbsolve.PythonForce("ctl", "bob", failing)])
    assert r.status == "failed"
    assert "python force 'ctl'" in r.message and "ValueError: controller saturated" in r.message
    assert isinstance(r.exception, ValueError)
    assert str(r.exception) == "controller saturated"
    n = len(r)
    assert 40 < n <= 51 and r.t[-1] <= 0.5 + 1e-12, (n, r.t[-1])
    assert r.summary["output_rows"] == n
    # the rows kept are the rows of the run that did not fail
    assert np.array_equal(r.data, full.data[:, :n])


def test_wrong_shape_and_unknown_body():
    r = pendulum("ode45").run(forces=[mbsolve.PythonForce("bad", "bob", lambda t, q, qd: [1.0])])
    assert r.status == "failed"
    assert "returned shape (1,), expected (3,)" in r.message
    with pytest.raises(mbsolve.ScenarioError) as e:
        pendulum("ode45").run(forces=[mbsolve.PythonForce("x", ["bob", "arm"], law)])
    assert "no body 'arm'" in str(e.value) and "bob" in str(e.value)
    with pytest.raises(mbsolve.ScenarioError) as e:
        pendulum("ode45").run(forces=[mbsolve.PythonForce("x", ["bob", "bob"], law)])
    assert "twice" in str(e.value)
    with pytest.raises(TypeError):
        mbsolve.PythonForce("x", "bob", 3.0)


def test_keyboard_interrupt_in_the_callback_is_interrupted():
    def ctrl_c(t, q, qd):
        if t > 0.3:
            raise KeyboardInterrupt
        return law(t, q, qd)

    r = pendulum("ode45").run(forces=[mbsolve.PythonForce("ctl", "bob", ctrl_c)])
    assert r.status == "interrupted"
    assert 0 < len(r) and r.t[-1] <= 0.3 + 1e-12


class PI:
    """A PI controller of the bob's angle: the torque reads the integral,
    which `step` advances once per accepted step (the rectangle rule)."""

    def __init__(self, target, kp, ki):
        self.target, self.kp, self.ki = target, kp, ki
        self.integral = 0.0
        self.t_last = None
        self.steps = 0

    def force(self, t, q, qd):
        e = self.target - q[2]
        return [0.0, 0.0, self.kp * e + self.ki * self.integral - 2.0 * qd[2]]

    def step(self, t, q, qd):
        if self.t_last is not None:
            self.integral += (self.target - q[2]) * (t - self.t_last)
        self.t_last = t
        self.steps += 1


def test_step_hook_keeps_controller_state():
    """Integral action removes the steady-state error a P controller leaves
    against gravity (m g l/2 cos φ / kp ≈ 0.12 rad here)."""
    target = 0.3
    results = {}
    for ki in (0.0, 40.0):
        pi = PI(target, kp=20.0, ki=ki)
        m = pendulum("ode45", end=8.0)
        m.python_force("pi", "bob", pi.force, step=pi.step)
        r = m.run()
        assert r.status == "completed"
        assert pi.steps == r.summary["steps"]  # once per accepted step
        results[ki] = r["bob.phi"][-1] - target
    assert abs(results[0.0]) > 0.1
    assert abs(results[40.0]) < 2e-3


def test_scenario_with_forces_and_pickle():
    import pickle

    sc = pendulum("ode45").scenario().with_forces(mbsolve.PythonForce("law", "bob", law))
    assert [f.name for f in sc.forces] == ["law"]
    r1 = sc.run()
    r2 = pickle.loads(pickle.dumps(sc)).run()
    assert np.array_equal(r1.data, r2.data)
    # overrides keep the forces
    assert sc.with_overrides(time__end=0.2).forces[0].name == "law"
