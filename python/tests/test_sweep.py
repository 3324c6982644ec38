"""Sweeps: the named reductions against NumPy on the result's columns, the
local sweep against runs one by one, and the Dask recipe (a LocalCluster
with two worker processes) against the local sweep."""

import math

import numpy as np
import pytest

import mbsolve
from conftest import SCENARIOS

FOURBAR = SCENARIOS / "fourbar.toml"


def test_reductions_equal_numpy_on_the_columns():
    r = mbsolve.load(FOURBAR, time__end=0.5).run()
    phi = r["coupler.phi"]
    t = r.t
    w = (t >= 0.1) & (t <= 0.3)
    assert r.reduce("final", "coupler.phi") == phi[-1]
    assert r.reduce("initial", "coupler.phi") == phi[0]
    assert r.reduce("max", "coupler.phi") == phi.max()
    assert r.reduce("min", "coupler.phi", (0.1, 0.3)) == phi[w].min()
    assert r.reduce("absmax", "coupler.phi") == np.abs(phi).max()
    assert r.reduce("final", "coupler.phi", (None, 0.3)) == phi[t <= 0.3][-1]
    # mean and rms: time averages by the trapezoidal rule (the library's
    # metrics, as `mbsolve sweep --metric`)
    span = t[w][-1] - t[w][0]
    trapezoid = getattr(np, "trapezoid", None) or np.trapz
    assert math.isclose(r.reduce("mean", "coupler.phi", (0.1, 0.3)),
                        trapezoid(phi[w], t[w]) / span, rel_tol=1e-12)
    assert math.isclose(r.reduce("rms", "coupler.phi", (0.1, 0.3)),
                        math.sqrt(trapezoid(phi[w] ** 2, t[w]) / span), rel_tol=1e-12)
    # an expression of columns, and the positional name of earlier versions
    assert r.reduce("max", "coupler.phi - crank.phi") == (phi - r["crank.phi"]).max()
    assert r.reduce("max", "phi2") == phi.max()
    assert np.array_equal(r["phi2"], phi) and "phi2" in r and "phi9" not in r
    # a crossing: the first time the angle passes its mean, between rows
    level = float(phi.mean())
    tc = r.reduce("crossing", "coupler.phi", threshold=level)
    k = int(np.nonzero(np.diff(np.sign(phi - level)))[0][0])
    assert t[k] <= tc <= t[k + 1]
    with pytest.raises(ValueError, match="not a reduction"):
        r.reduce("median", "coupler.phi")
    with pytest.raises(ValueError, match="no output row"):
        r.reduce("max", "coupler.phi", (3.0, 4.0))
    with pytest.raises(KeyError, match="no column 'phi9'"):
        r.reduce("max", "phi9")


def metric_amplitude(result):
    """A Python metric: the rocker's peak-to-peak swing [rad]."""
    return float(np.ptp(result["rocker.phi"]))


PARAMS = {"stabilization.alpha": [0.0, 10.0], "time.end": [0.2, 0.4]}
METRICS = {
    "drift": "max(constraint_norm)",
    "phi2_rms": "rms(coupler.phi, 0.1, 0.2)",
    "final_x2": ("final", "coupler.x"),
    "steps": "steps",
    "amplitude": metric_amplitude,
}


def test_local_sweep_equals_runs_one_by_one():
    sc = mbsolve.load(FOURBAR, stabilization__rule="equal")
    df = mbsolve.sweep(sc, PARAMS, METRICS, workers=2)
    assert list(df.columns) == ["stabilization.alpha", "time.end", "status", "message", "rows",
                                "drift", "phi2_rms", "final_x2", "steps", "amplitude"]
    # product, first key slowest
    assert df["stabilization.alpha"].tolist() == [0.0, 0.0, 10.0, 10.0]
    assert df["time.end"].tolist() == [0.2, 0.4, 0.2, 0.4]
    for i, row in df.iterrows():
        r = sc.run({"stabilization.alpha": row["stabilization.alpha"],
                    "time.end": row["time.end"]})
        assert row["status"] == r.status == "completed"
        assert row["rows"] == len(r)
        assert row["drift"] == r["constraint_norm"].max()
        assert row["final_x2"] == r["coupler.x"][-1]
        assert row["steps"] == r.summary["steps"]
        assert row["amplitude"] == np.ptp(r["rocker.phi"])
    # stabilization reduces the drift (the paper's point)
    assert df["drift"][3] < df["drift"][1]
    # a list of metrics is named by the specs; a typo fails before any run
    df2 = mbsolve.sweep(sc, [{"time.end": 0.1}], ["max(crank.phi)"])
    assert list(df2.columns)[-1] == "max(crank.phi)"
    with pytest.raises(mbsolve.ScenarioError):
        mbsolve.sweep(sc, {"stabilization.alfa": [1.0]}, METRICS)
    with pytest.raises(ValueError, match="unknown reduction"):
        mbsolve.sweep(sc, PARAMS, {"x": "median(coupler.phi)"})


def test_dask_sweep_equals_local_sweep():
    distributed = pytest.importorskip("dask.distributed")
    sc = mbsolve.load(FOURBAR, stabilization__rule="equal")
    local = mbsolve.sweep(sc, PARAMS, METRICS)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None, host="127.0.0.1") as cluster, \
            distributed.Client(cluster) as client:
        assert len(client.scheduler_info()["workers"]) == 2
        remote = mbsolve.sweep(sc, PARAMS, METRICS, client=client)
    # the same table to the last bit (NaN-free metrics; messages None)
    assert remote.equals(local), (remote, local)
