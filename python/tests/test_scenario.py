"""Scenarios from Python: load, overrides, check, run; results against the
CLI's files (same numbers to the last printed digit, same columns and
units), NumPy views, pandas and Arrow."""

import csv
import json
import subprocess

import numpy as np
import pytest

import mbsolve
from conftest import SCENARIOS


def read_cli_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def test_fourbar_equals_cli_csv_to_the_last_digit(cli, tmp_path):
    """The four-bar from Python equals `mbsolve run`'s CSV: every value
    printed as the CSV prints it ({:.12e}) is the same text, and the
    columns, units and summary figures agree."""
    path = SCENARIOS / "fourbar.toml"
    sets = ["time.end=0.5", "stabilization.alpha=5"]
    cmd = [str(cli), "run", str(path), "--out", str(tmp_path), "--quiet"]
    for s in sets:
        cmd += ["--set", s]
    subprocess.run(cmd, check=True)
    header, rows = read_cli_csv(tmp_path / "fourbar.csv")
    units = json.loads((tmp_path / "fourbar.columns.json").read_text())
    summary = json.loads((tmp_path / "fourbar.summary.json").read_text())

    r = mbsolve.load(path, {"time.end": 0.5}, stabilization__alpha=5).run()
    assert r.status == "completed"
    assert r.columns == header
    assert r.units == {c["name"]: c["unit"] for c in units}
    assert len(r) == len(rows) > 10
    for k, name in enumerate(header):
        py = [f"{v:.12e}" for v in r[name]]
        cli_col = [row[k] for row in rows]
        # Rust's {:.12e} writes e.g. 1.5e0, Python 1.5e+00: compare as the
        # same decimal (mantissa text and exponent value)
        for a, b in zip(py, cli_col):
            ma, ea = a.split("e")
            mb, eb = b.split("e")
            assert (ma, int(ea)) == (mb, int(eb)), (name, a, b)
    for key in ["steps", "failed_steps", "rhs_evals", "output_rows", "status",
                "max_constraint_norm", "final_constraint_norm", "method"]:
        assert r.summary[key] == summary[key], key
    assert r.summary["overrides"] == summary["overrides"] == sets


def test_columns_are_views_of_one_block():
    r = mbsolve.load(SCENARIOS / "fourbar.toml", time__end=0.1).run()
    x1 = r["crank.x"]
    assert isinstance(x1, np.ndarray) and x1.dtype == np.float64
    assert not x1.flags.writeable
    # a view into the table held by Rust: no copy per column or value
    assert np.shares_memory(x1, r.data)
    assert x1.base is not None
    assert r.columns[:4] == ["t", "crank.x", "crank.y", "crank.phi"]
    assert r.data.shape == (len(r.columns), len(r))
    assert r.t[0] == 0.0 and abs(r.t[-1] - 0.1) < 1e-12


def test_pandas_and_arrow_carry_names_units_and_values():
    pa = pytest.importorskip("pyarrow")
    pytest.importorskip("pandas")
    r = mbsolve.load(SCENARIOS / "fourbar.toml", time__end=0.1).run()
    df = r.to_pandas()
    assert list(df.columns) == r.columns
    assert np.array_equal(df["coupler.phi"].to_numpy(), r["coupler.phi"])
    assert df.attrs["units"]["crank.x"] == "m" and df.attrs["units"]["crank.phi"] == "rad"
    tab = r.to_arrow()
    assert tab.schema.names == r.columns
    assert tab.schema.field("t").metadata == {b"unit": b"s"}
    assert tab.schema.field("constraint_norm").metadata[b"unit"] == b"m"
    assert np.array_equal(tab.column("rocker.y").to_numpy(), r["rocker.y"])
    assert json.loads(tab.schema.metadata[b"summary"])["status"] == "completed"
    assert isinstance(tab, pa.Table)


def test_arrow_units_equal_the_library_arrow_file(cli, tmp_path):
    """The field metadata equals the library's own Arrow IPC output."""
    pa_ipc = pytest.importorskip("pyarrow.ipc")
    path = SCENARIOS / "fourbar.toml"
    subprocess.run([str(cli), "run", str(path), "--out", str(tmp_path), "--quiet",
                    "--set", "time.end=0.1", "--set", "output.format=arrow"], check=True)
    with pa_ipc.open_file(tmp_path / "fourbar.arrow") as f:
        cli_tab = f.read_all()
    r = mbsolve.load(path, time__end=0.1).run()
    tab = r.to_arrow()
    assert [f.metadata for f in tab.schema] == [f.metadata for f in cli_tab.schema]
    for name in cli_tab.schema.names:
        assert np.array_equal(tab.column(name).to_numpy(), cli_tab.column(name).to_numpy())


def test_check_matches_the_cli(cli):
    path = SCENARIOS / "fourbar.toml"
    c = mbsolve.load(path).check()
    out = subprocess.run([str(cli), "check", str(path)], check=True,
                         capture_output=True, text=True).stdout
    lines = {l[:22].strip(): l[22:].strip() for l in out.splitlines()}
    assert c["bodies"] == int(lines["bodies"]) == 3
    assert c["coordinates"] == int(lines["coordinates"]) == 9
    assert c["constraint_equations"] == int(lines["constraint equations"]) == 8
    assert c["dof"] == int(lines["degrees of freedom"]) == 1
    assert c["redundant"] == int(lines["redundant equations"]) == 0
    assert len(c["joints"]) == int(lines["joints"].split()[0]) == 4
    # the torque and gravity
    assert len(c["forces"]) == int(lines["force elements"].split()[0]) == 2
    assert lines["method"].startswith(c["method"])


def test_overrides_as_dict_and_keywords_and_with_overrides():
    base = mbsolve.load(SCENARIOS / "fourbar.toml")
    a = base.with_overrides({"time.end": 0.2}).run(stabilization__alpha=5.0)
    b = mbsolve.load(SCENARIOS / "fourbar.toml", {"time.end": "0.2",
                                                  "stabilization.alpha": 5}).run()
    assert a.summary["t_end"] == 0.2
    assert np.array_equal(a.data, b.data)
    assert mbsolve.override_specs({"body[1].mass": 2.5}, integrator__method="ode45",
                                  initial__incorrect=True, x=[1, 2.5, "a"]) == [
        "body[1].mass=2.5", "integrator.method=ode45", "initial.incorrect=true",
        'x=[1, 2.5, "a"]']


def test_from_toml_and_builtin_equal_the_file():
    text = (SCENARIOS / "fourbar.toml").read_text()
    a = mbsolve.Scenario.from_toml(text, time__end=0.1).run()
    b = mbsolve.builtin("fourbar", time__end=0.1).run()
    c = mbsolve.load(SCENARIOS / "fourbar.toml", time__end=0.1).run()
    assert np.array_equal(a.data, c.data) and np.array_equal(b.data, c.data)
    assert a.summary["scenario"] == "<string>"


def test_every_shipped_scenario_checks():
    for p in sorted(SCENARIOS.glob("*.toml")):
        c = mbsolve.load(p).check()
        assert c["coordinates"] == 3 * c["bodies"] + c["states"], p
        assert c["dof"] == c["coordinates"] - c["states"] - c["rank"], p


def test_help_and_docstrings():
    assert mbsolve.__doc__ and "load" in mbsolve.__doc__
    for f in [mbsolve.load, mbsolve.builtin, mbsolve.Scenario.run, mbsolve.Scenario.check,
              mbsolve.Result.to_pandas, mbsolve.Result.to_arrow, mbsolve.Scenario.from_toml]:
        assert f.__doc__, f
