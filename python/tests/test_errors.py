"""Errors across the boundary: bad input raises ValueError naming the key
path, a Rust panic becomes an exception, two runs in two threads give the
same bits as one after the other, Ctrl-C ends a run as "interrupted"."""

import _thread
import threading

import numpy as np
import pytest

import mbsolve
from conftest import SCENARIOS

FOURBAR = SCENARIOS / "fourbar.toml"


def test_bad_value_raises_value_error_with_the_key_path():
    with pytest.raises(ValueError) as e:
        mbsolve.load(FOURBAR, {"body[1].mass": -2.0})
    err = e.value
    assert isinstance(err, mbsolve.ScenarioError)
    assert err.key == "body[1].mass"
    assert "--set body[1].mass" in err.file and "fourbar.toml" in err.file
    assert "-2" in err.problem


def test_unknown_key_and_bad_override_syntax():
    with pytest.raises(mbsolve.ScenarioError) as e:
        mbsolve.load(FOURBAR, stabilization__alfa=3)
    assert "alfa" in str(e.value)
    with pytest.raises(mbsolve.ScenarioError) as e:
        mbsolve.load(FOURBAR, {"body[7].mass": 1.0})
    assert "body[7] does not exist" in str(e.value)
    with pytest.raises(mbsolve.ScenarioError):
        mbsolve.load(FOURBAR, {"time.end": float("nan")})
    with pytest.raises(mbsolve.ScenarioError):
        mbsolve.load(FOURBAR, {"time.end": object()})


def test_bad_toml_text_and_missing_file(tmp_path):
    with pytest.raises(ValueError) as e:
        mbsolve.Scenario.from_toml("[[body]\nmass = 1", file="broken.toml")
    assert e.value.file == "broken.toml" and e.value.key == "line 1"
    with pytest.raises(ValueError) as e:
        mbsolve.load(tmp_path / "nope.toml")
    assert "cannot read" in str(e.value) and e.value.key == "-"


def test_bad_override_at_run_time_raises_too():
    sc = mbsolve.load(FOURBAR)
    with pytest.raises(ValueError) as e:
        sc.run(integrator__method="no-such-method")
    assert e.value.key.startswith("integrator")


def test_a_rust_panic_is_an_exception_not_a_crash():
    with pytest.raises(RuntimeError) as e:
        mbsolve._mbsolve._panic_for_test()
    assert "a deliberate panic" in str(e.value)
    # the interpreter and the library still work afterwards
    assert mbsolve.load(FOURBAR, time__end=0.05).run().status == "completed"


def test_two_threads_give_the_bits_of_one_after_the_other():
    a = mbsolve.load(FOURBAR, time__end=0.5, stabilization__alpha=5)
    b = mbsolve.load(FOURBAR, time__end=0.5, integrator__method="ode45")
    seq = [a.run().data.copy(), b.run().data.copy()]
    out = [None, None]

    def work(k, sc):
        out[k] = sc.run().data

    threads = [threading.Thread(target=work, args=(k, sc)) for k, sc in enumerate([a, b])]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for k in range(2):
        assert out[k] is not None
        assert out[k].tobytes() == seq[k].tobytes()


def test_ctrl_c_ends_the_run_as_interrupted_keeping_rows():
    # the falling rod over 100 s runs for tens of seconds (its 1 s takes a
    # fraction of one on a quiet machine): interrupt it after 0.3 s
    sc = mbsolve.builtin("falling_rod").with_overrides(
        {"time.end": 100, "output.dt": 0.01})
    timer = threading.Timer(0.3, _thread.interrupt_main)
    timer.start()
    try:
        r = sc.run()
    finally:
        timer.cancel()
    assert r.status == "interrupted", r.summary
    assert "KeyboardInterrupt" in r.message
    assert len(r) == r.summary["output_rows"] > 0
    assert np.all(np.diff(r.t) > 0)


def test_repr_of_a_scenario_whose_construction_failed():
    """A traceback or debugger shows the half-built object: its repr says
    so instead of raising AttributeError."""
    seen = []

    class Keep(mbsolve.Scenario):
        __slots__ = ()

        def __init__(self, *args, **kwargs):
            seen.append(self)
            super().__init__(*args, **kwargs)

    with pytest.raises(mbsolve.ScenarioError):
        Keep("[time\nend = ", file="bad.toml")
    assert repr(seen[0]) == "Scenario(<invalid: construction failed>, file='bad.toml')"
    # never started: no slot set at all
    assert "construction failed" in repr(mbsolve.Scenario.__new__(mbsolve.Scenario))
    good = mbsolve.load(FOURBAR, time__end=0.1)
    assert repr(good).startswith("Scenario('fourbar'")
