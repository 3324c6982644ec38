"""Scenarios with ``[[state]]`` controller states from Python: the state
columns (by name, with their units) equal the CLI's, ``check()`` counts
them, and a :class:`mbsolve.Model` with a state equals the scenario text
and follows the closed form of a first-order lag."""

import csv
import json
import subprocess

import numpy as np

import mbsolve
from conftest import SCENARIOS


def test_pid_arm_state_columns_equal_the_cli(cli, tmp_path):
    path = SCENARIOS / "pid_arm.toml"
    subprocess.run([str(cli), "run", str(path), "--out", str(tmp_path), "--quiet",
                    "--set", "time.end=1.0"], check=True)
    with open(tmp_path / "pid_arm.csv", newline="") as f:
        rows = list(csv.reader(f))
    header, rows = rows[0], rows[1:]
    units = {c["name"]: c["unit"]
             for c in json.loads((tmp_path / "pid_arm.columns.json").read_text())}
    r = mbsolve.load(path, time__end=1.0).run()
    assert r.status == "completed"
    assert r.columns == header
    for name in ["e1", "e2", "e3"]:
        assert name in r
        assert r.units[name] == units[name] == "rad s"
        k = header.index(name)
        cli_col = np.array([float(row[k]) for row in rows])
        # the CSV prints 13 significant digits
        assert np.allclose(r[name], cli_col, rtol=1e-12, atol=1e-15), name
        assert np.abs(r[name]).max() > 1e-3, name
    assert r.label("e1") == "e1 [rad s]"


def test_check_counts_the_states():
    c = mbsolve.load(SCENARIOS / "pid_arm.toml").check()
    assert (c["bodies"], c["states"], c["coordinates"], c["dof"]) == (3, 3, 12, 3)


LAG_TOML = """name = "lag"
gravity = [0.0, -9.81]

[parameters]
tau = 0.2

[[body]]
name = "m"
mass = 1.0
inertia = 0.1

[[joint]]
type = "revolute"
body_i = "ground"
point_i = [0.0, 0.0]
body_j = "m"
point_j = [0.0, 0.0]

[[state]]
name = "lag"
derivative = "(1 - lag)/tau"
unit = "V"

[integrator]
method = "ode45"
rtol = 1e-10
atol = 1e-12

[time]
end = 1.0

[output]
dt = 0.05
"""


def lag_model():
    m = mbsolve.Model("lag", gravity=[0.0, -9.81])
    m.parameters(tau=0.2)
    m.body("m", mass=1.0, inertia=0.1)
    m.joint("revolute", body_i="ground", point_i=[0.0, 0.0], body_j="m", point_j=[0.0, 0.0])
    m.state("lag", "(1 - lag)/tau", unit="V")
    m.integrator(method="ode45", rtol=1e-10, atol=1e-12).time(end=1.0).output(dt=0.05)
    return m


def test_model_with_a_state_equals_the_text_and_the_closed_form():
    m = lag_model()
    a = m.run()
    b = mbsolve.Scenario.from_toml(LAG_TOML, name="lag").run()
    assert a.columns == b.columns and a.units == b.units
    assert a.data.tobytes() == b.data.tobytes()
    assert a.units["lag"] == "V"
    closed = 1.0 - np.exp(-a.t / 0.2)
    assert np.abs(a["lag"] - closed).max() < 1e-8
    assert a["lag"][-1] > 0.99
    assert m.check()["states"] == 1
    assert "[[state]]" in m.to_toml() and "[parameters]" in m.to_toml()


def test_model_state_errors_name_the_key():
    m = lag_model().state("bad", "-nosuch")
    try:
        m.check()
    except ValueError as e:
        assert e.key == "state[1].derivative" and "nosuch" in str(e)
    else:
        raise AssertionError("no error")
