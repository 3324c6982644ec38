"""Models built in Python: the same validation and messages as the
scenario reader, and the same bits as the equivalent scenario file."""

import numpy as np
import pytest

import mbsolve
from conftest import SCENARIOS


def fourbar_model():
    m = mbsolve.Model("fourbar", gravity=(0.0, -9.81),
                      description="Four-bar mechanism built in Python")
    m.body("crank", mass=0.2, inertia=6.666666666666667e-4, x=0.05, y=0.0866,
           phi_deg=60.0, omega=6.283185307179586)
    m.body("coupler", mass=0.4, inertia=5.333333333333333e-3, x=0.298, y=0.202, phi_deg=8.3)
    m.body("rocker", mass=0.25, inertia=1.3020833333333333e-3, x=0.448, y=0.1155,
           phi_deg=67.5)
    for name, bi, pi, bj, pj in [
        ("A", "ground", [0.0, 0.0], "crank", [-0.1, 0.0]),
        ("B", "crank", [0.1, 0.0], "coupler", [-0.2, 0.0]),
        ("C", "coupler", [0.2, 0.0], "rocker", [0.125, 0.0]),
        ("D", "ground", [0.4, 0.0], "rocker", [-0.125, 0.0]),
    ]:
        m.joint("revolute", name=name, body_i=bi, point_i=pi, body_j=bj, point_j=pj)
    m.force("torque", name="M", body="crank", torque=0.5)
    m.initial(independent=["crank.phi"], incorrect=False,
              perturbation=[{"coordinate": "coupler.phi", "delta": 0.05}])
    m.integrator(method="ode23").time(end=2.0).output(dt=0.002)
    return m


def test_fourbar_model_equals_the_scenario_file_bit_for_bit():
    sets = {"time.end": 0.5, "stabilization.alpha": 5}
    a = fourbar_model().run(sets)
    b = mbsolve.load(SCENARIOS / "fourbar.toml", sets).run()
    assert a.columns == b.columns and a.units == b.units
    assert a.data.tobytes() == b.data.tobytes()
    assert a.summary["steps"] == b.summary["steps"] > 10


def test_spring_pendulum_model_equals_the_file():
    m = mbsolve.Model("spring_pendulum", gravity=[0.0, -9.81])
    m.body("bob", mass=1.0, inertia=0.01, x=0.4, y=-0.6928203230275509)
    m.force("spring", name="spring", body_i="ground", point_i=[0.0, 0.0], body_j="bob",
            point_j=[0.0, 0.0], free_length=0.5, stiffness=60.0, damping=0.0)
    m.integrator(method="ode45", rtol=1e-9, atol=1e-12).time(end=0.5).output(dt=0.01)
    a = m.run()
    b = mbsolve.load(SCENARIOS / "spring_pendulum.toml", time__end=0.5).run()
    assert a.data.tobytes() == b.data.tobytes()


def test_to_toml_reads_back_to_the_same_document():
    tomllib = pytest.importorskip("tomllib")
    m = fourbar_model()
    text = m.to_toml()
    assert tomllib.loads(text) == m.to_dict()
    assert "[[body]]" in text and "[initial]" in text
    # values keep their bits through the text
    assert tomllib.loads(text)["body"][0]["inertia"] == 6.666666666666667e-4


def test_model_errors_are_the_readers_with_element_and_key():
    m = fourbar_model()
    m.body("extra", mass=-1.0, inertia=1.0)
    with pytest.raises(ValueError) as e:
        m.scenario()
    assert e.value.key == "body[3].mass" and "<model fourbar>" in e.value.file
    m = fourbar_model()
    m.force("spring", body_i="ground", point_i=[0, 0], body_j="crank", point_j=[0, 0],
            stiffnes=1.0)
    with pytest.raises(ValueError) as e:
        m.check()
    assert e.value.key.startswith("force[1]") and "stiffnes" in str(e.value)
    m = fourbar_model()
    m.joint("revolute", body_i="ground", point_i=[0, 0], body_j="nobody", point_j=[0, 0])
    with pytest.raises(ValueError) as e:
        m.check()
    assert "joint[4]" in e.value.key and "nobody" in str(e.value)


def test_model_check_counts():
    c = fourbar_model().check()
    assert (c["bodies"], c["dof"], c["redundant"]) == (3, 1, 0)
