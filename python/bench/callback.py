"""Cost of a Python force per call, measured in one session (not a test):
the pendulum of python/tests/test_callback.py over T seconds with ode45 at
tight tolerances, its law as an `expression` force (compiled, no Python)
and as a PythonForce; the difference of the two runs' wall times divided
by the number of calls. Also the expression force plus a no-op
PythonForce (the same trajectory: the crossing alone — GIL, lists in and
out, the adapter's arrays) and the law's own time in plain Python.

    python python/bench/callback.py [--end 20] [--repeats 5]
"""

import argparse
import math
import statistics
import sys
import time

import numpy as np

import mbsolve

LAW = "-2*bob.phi - 0.1*bob.omega + 0.3*sin(3*t)"


def law(t, q, qd):
    return [0.0, 0.0, -2.0 * q[2] - 0.1 * qd[2] + 0.3 * math.sin(3.0 * t)]


def model(end, expression):
    m = mbsolve.Model("pendulum", gravity=(0.0, -9.81))
    m.body("bob", mass=1.0, inertia=0.02, x=0.5, y=0.0, phi=0.0)
    m.joint("revolute", body_i="ground", point_i=[0.0, 0.0], body_j="bob",
            point_j=[-0.5, 0.0])
    if expression:
        m.force("expression", name="law", body="bob", torque=LAW)
    m.integrator(method="ode45", rtol=1e-10, atol=1e-12).time(end=end).output(dt=0.01)
    return m.scenario()


def timed(sc, forces, repeats):
    walls = []
    for _ in range(repeats):
        t = time.perf_counter()
        r = sc.run(forces=forces)
        walls.append(time.perf_counter() - t)
        assert r.status == "completed", r.message
    return statistics.median(walls), r


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--end", type=float, default=20.0)
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args()
    calls = []

    def counted(t, q, qd):
        calls.append(1)
        return law(t, q, qd)

    expr_wall, r0 = timed(model(a.end, True), [], a.repeats)
    py_wall, r1 = timed(model(a.end, False), [mbsolve.PythonForce("law", "bob", law)], a.repeats)
    noop = [0.0, 0.0, 0.0]
    noop_wall, _ = timed(model(a.end, True),
                         [mbsolve.PythonForce("noop", "bob", lambda t, q, qd: noop)], a.repeats)
    model(a.end, False).run(forces=[mbsolve.PythonForce("law", "bob", counted)])
    n = len(calls)
    q = np.zeros(3)
    t = time.perf_counter()
    for i in range(n):
        law(0.1, q, q)
    own = (time.perf_counter() - t) / n
    dphi = float(np.max(np.abs(r0["bob.phi"] - r1["bob.phi"])))
    print(f"pendulum, ode45 rtol 1e-10, {a.end} s: {n} calls "
          f"({r1.summary['rhs_evals']} right-hand sides), median of {a.repeats}")
    print(f"  expression force: {expr_wall:.4f} s; PythonForce: {py_wall:.4f} s; "
          f"no-op PythonForce: {noop_wall:.4f} s; max |dphi| {dphi:.1e}")
    print(f"  per call: {(py_wall - expr_wall) / n * 1e6:.2f} us over the expression force, "
          f"crossing alone (no-op law) {(noop_wall - expr_wall) / n * 1e6:.2f} us, "
          f"the law's own Python {own * 1e6:.2f} us")


if __name__ == "__main__":
    sys.exit(main())
