"""Progress display and plots: the progress callable sees the run's time
span and increasing times; the own line and tqdm's bar end at the run's
end; Result.plot labels axes with the units of columns.json."""

import io
import time

import pytest

import mbsolve
from conftest import SCENARIOS

FOURBAR = SCENARIOS / "fourbar.toml"


def long_run():
    """The four-bar made slow in wall time (a Python force that sleeps
    0.5 ms per call and adds nothing), for several progress calls."""
    def slow(t, q, qd):
        time.sleep(5e-4)
        return [0.0, 0.0, 0.0]

    return mbsolve.load(FOURBAR).with_forces(mbsolve.PythonForce("slow", "crank", slow))


def test_progress_callable_sees_increasing_times():
    seen = []
    r = long_run().run(progress=lambda t, t0, t_end: seen.append((t, t0, t_end)))
    assert r.status == "completed"
    assert r.summary["wall_s"] > 0.3 and len(seen) >= 2, (r.summary["wall_s"], len(seen))
    # at most one call per 0.1 s of wall time
    assert len(seen) <= r.summary["wall_s"] / 0.1 + 1
    ts = [s[0] for s in seen]
    assert ts == sorted(ts) and all(0.0 < t <= 2.0 for t in ts)
    assert all(s[1:] == (0.0, 2.0) for s in seen)


def test_own_progress_line_and_tqdm():
    from mbsolve._progress import Progress

    out = io.StringIO()
    p = Progress("fourbar", file=out, use_tqdm=False)
    p(1.0, 0.0, 4.0)
    p(4.0, 0.0, 4.0)
    p.close()
    text = out.getvalue()
    assert text.startswith("\rfourbar: [########") and "t = 1/4 s ( 25 %)" in text
    assert "t = 4/4 s (100 %)" in text and text.endswith("\n")
    pytest.importorskip("tqdm")
    out = io.StringIO()
    p = Progress("fourbar", file=out)
    p(2.0, 0.0, 4.0)
    p(4.0, 0.0, 4.0)
    p.close()
    assert "t = 4/4 s" in out.getvalue()
    with pytest.raises(TypeError):
        long_run().run(progress="yes")


def test_plot_labels_with_units():
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    r = mbsolve.load(FOURBAR, time__end=0.2).run()
    ax = r.plot("crank.phi")
    assert ax.get_xlabel() == "t [s]" and ax.get_ylabel() == "crank.phi [rad]"
    line = ax.get_lines()[0]
    assert (line.get_xdata() == r.t).all() and (line.get_ydata() == r["crank.phi"]).all()
    ax = r.plot("crank.x", "crank.y")
    assert ax.get_ylabel() == "[m]" and len(ax.get_legend().get_texts()) == 2
    # positional names of earlier versions plot the named columns
    ax = r.plot("x1", "phi3")
    assert ax.get_ylabel() == "crank.x [m], rocker.phi [rad]"
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["crank.x", "rocker.phi"]
    ax = r.plot()
    assert ax.get_ylabel() == "constraint_norm [m]" and ax.get_yscale() == "log"
    with pytest.raises(KeyError):
        r.plot("nope")
