"""mbsolve: dynamics of constrained planar multibody systems, from Python.

The package wraps the Rust library ``mbsolve`` (the same code the ``mbsolve``
command runs; nothing is implemented twice):

- :func:`load` reads a scenario file, :meth:`Scenario.from_toml` takes its
  text; overrides use the command line's ``--set`` key paths
  (``{"stabilization.alpha": 10}`` or ``stabilization__alpha=10``);
- :meth:`Scenario.check` returns what ``mbsolve check`` prints, as a dict;
- :meth:`Scenario.run` runs it with the GIL released and returns a
  :class:`Result`: the columns of ``mbsolve run``'s CSV as NumPy arrays
  (views of one block, no copy per value), :meth:`Result.to_pandas`,
  :meth:`Result.to_arrow` (units in the field metadata), the summary as a
  dict and the warnings as a list; ``progress=True`` shows a progress bar
  (tqdm if installed), :meth:`Result.plot` draws columns with matplotlib;
- :class:`PythonForce`: a force law or controller written in Python,
  called from the running integration (``run(forces=[...])``);
- :class:`Model` builds a scenario in Python (``to_toml`` writes its file);
- :func:`sweep` runs a scenario for a grid of overrides in parallel and
  returns one row per run with metrics (``final``, ``max``, ``min``,
  ``rms`` reductions or Python functions); ``mbsolve.dask`` spreads the
  same sweep over a Dask cluster.

Errors: an invalid scenario or override raises :class:`ScenarioError` (a
``ValueError``) naming the file and the key path; a run that cannot start
raises :class:`RunError` (a ``RuntimeError``); a run that fails midway or is
interrupted (Ctrl-C) returns a ``Result`` whose ``status`` says so, with the
rows computed so far. A Rust panic is caught and raised as ``RuntimeError``.

Example::

    import mbsolve
    sc = mbsolve.load("scenarios/fourbar.toml", stabilization__alpha=10)
    print(sc.check()["dof"])            # 1
    r = sc.run()
    print(r.status, r.summary["max_constraint_norm"])
    df = r.to_pandas()                   # columns t, crank.x, crank.y, crank.phi, ...
"""

from __future__ import annotations

import json
import math
import os
from typing import Any, Dict, Iterable, List, Mapping, Optional, Tuple, Union

import numpy as np

from . import _mbsolve, _progress
from ._mbsolve import RunError, ScenarioError
from ._progress import ProgressArg
from .forces import PythonForce

__version__: str = _mbsolve.__version__

__all__ = [
    "Scenario",
    "Result",
    "PythonForce",
    "ScenarioError",
    "RunError",
    "load",
    "builtin",
    "override_specs",
    "__version__",
]

OverrideValue = Union[bool, int, float, str, List[Any], Tuple[Any, ...]]


def _toml_value(v: Any, key: str) -> str:
    """The text of an override value as the command line's ``--set`` reads
    it: booleans, numbers and lists as TOML values; a string verbatim (read
    as TOML if it is one, e.g. ``"[1, 2]"``, else as a bare string, as
    ``--set integrator.method=ode45``)."""
    if isinstance(v, bool) or isinstance(v, np.bool_):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        f = float(v)
        if math.isnan(f):
            return "nan"
        if math.isinf(f):
            return "inf" if f > 0 else "-inf"
        return repr(f)  # shortest round-trip decimal
    if isinstance(v, str):
        return v
    if isinstance(v, (list, tuple, np.ndarray)):
        parts = [json.dumps(x) if isinstance(x, str) else _toml_value(x, key) for x in v]
        return "[" + ", ".join(parts) + "]"
    raise ScenarioError(
        f"override {key}: a value of type {type(v).__name__} is not a scenario value "
        "(bool, int, float, str or a list of them)"
    )


def override_specs(
    overrides: Optional[Mapping[str, OverrideValue]] = None, **kwargs: OverrideValue
) -> List[str]:
    """The ``KEY=VALUE`` specs of ``mbsolve run --set`` for a dict of key
    paths (``{"body[1].mass": 2.0}``) and keyword arguments, in which a
    double underscore stands for the dot (``stabilization__alpha=10`` is
    ``stabilization.alpha=10``). Applied in order: the dict, then the
    keywords."""
    specs = []
    items = list((overrides or {}).items()) + [
        (k.replace("__", "."), v) for k, v in kwargs.items()
    ]
    for k, v in items:
        if not isinstance(k, str):
            raise ScenarioError(f"override key {k!r} is not a string (a key path such as time.end)")
        specs.append(f"{k}={_toml_value(v, k)}")
    return specs


class Scenario:
    """A validated scenario: its TOML text, the file it came from and the
    ``--set`` overrides applied to it. Immutable; :meth:`with_overrides`
    returns a new one. Built by :func:`load`, :meth:`from_toml` or
    ``Model.scenario()``."""

    __slots__ = ("_text", "_file", "_stem", "_overrides", "_name", "_forces")

    def __init__(self, text: str, file: str = "<string>", stem: str = "scenario",
                 overrides: Iterable[str] = (), forces: Iterable[PythonForce] = ()) -> None:
        self._text = str(text)
        self._file = str(file)
        self._stem = str(stem)
        self._overrides = list(overrides)
        self._forces = _check_forces(forces)
        self._name = _mbsolve.validate(self._text, self._file, self._stem, self._overrides)

    @classmethod
    def from_toml(cls, text: str, overrides: Optional[Mapping[str, OverrideValue]] = None,
                  *, name: str = "scenario", file: str = "<string>",
                  **kwargs: OverrideValue) -> "Scenario":
        """A scenario from TOML text (the scenario file format); ``name`` is
        its name when the text gives none, ``file`` names it in errors."""
        return cls(text, file, name, override_specs(overrides, **kwargs))

    @property
    def name(self) -> str:
        """The scenario's name (its ``name`` key, else the file stem)."""
        return self._name

    @property
    def text(self) -> str:
        """The scenario's TOML text (without the overrides)."""
        return self._text

    @property
    def file(self) -> str:
        """The file (or ``<string>``) named in errors."""
        return self._file

    @property
    def overrides(self) -> List[str]:
        """The ``KEY=VALUE`` overrides, in the order they apply."""
        return list(self._overrides)

    @property
    def forces(self) -> List[PythonForce]:
        """The :class:`PythonForce` laws added to every run of this scenario."""
        return list(self._forces)

    def with_overrides(self, overrides: Optional[Mapping[str, OverrideValue]] = None,
                       **kwargs: OverrideValue) -> "Scenario":
        """A new scenario with more overrides (after the present ones)."""
        return Scenario(self._text, self._file, self._stem,
                        self._overrides + override_specs(overrides, **kwargs), self._forces)

    def with_forces(self, *forces: PythonForce) -> "Scenario":
        """A new scenario with more :class:`PythonForce` laws (after the
        present ones)."""
        return Scenario(self._text, self._file, self._stem, self._overrides,
                        self._forces + _check_forces(forces))

    def check(self) -> Dict[str, Any]:
        """What ``mbsolve check`` reports, as a dict: ``bodies``,
        ``coordinates`` (the bodies' and the controller states'),
        ``states`` (how many ``[[state]]``), ``constraint_equations``,
        ``rank`` (of Φ_q at the initial state), ``dof`` (besides the
        states), ``redundant``, ``joints`` and ``forces``
        (element descriptions), ``sensors``, ``evaluation``, ``method``,
        ``formulation``, ``linear_solver``, ``t0``, ``t_end``, ``output_dt``
        [s] and, when the initial state was assembled, ``initial_assembly``."""
        return json.loads(_mbsolve.check_json(self._text, self._file, self._stem, self._overrides))

    def run(self, overrides: Optional[Mapping[str, OverrideValue]] = None, *,
            forces: Iterable[PythonForce] = (), progress: ProgressArg = False,
            _one_thread: bool = False, **kwargs: OverrideValue) -> "Result":
        """Run the scenario (with further overrides, if given) and return its
        :class:`Result`. The GIL is released while it runs (and taken only
        to call Python forces and the progress display); Ctrl-C ends it with
        status ``"interrupted"`` and the rows so far.

        ``forces``: :class:`PythonForce` laws added for this run (after the
        scenario's own). ``progress``: ``True`` for a progress bar (tqdm if
        installed — in Jupyter its widget — else one line on stderr), or a
        callable ``progress(t, t0, t_end)`` called at most every 0.1 s.

        Raises :class:`ScenarioError` for an invalid override or a Python
        force naming a body the scenario lacks, :class:`RunError` when the
        run cannot start."""
        specs = self._overrides + override_specs(overrides, **kwargs)
        laws = self._forces + _check_forces(forces)
        bar = _progress.make(progress, self._name)
        try:
            table, names, units, summary, raised = _mbsolve.run(
                self._text, self._file, self._stem, specs, True,
                [f._spec() for f in laws], bar, _one_thread)
        finally:
            if isinstance(bar, _progress.Progress):
                bar.close()
        return Result(table, names, units, json.loads(summary), raised)

    def __reduce__(self) -> Tuple[Any, ...]:
        """Pickled as its text, file, name, overrides and Python forces
        (for Dask workers; lambdas need cloudpickle, which Dask uses)."""
        return (Scenario, (self._text, self._file, self._stem, self._overrides, self._forces))

    def __repr__(self) -> str:
        # also for an object whose construction raised (a traceback or a
        # debugger showing it): its slots may be unset
        name = getattr(self, "_name", None)
        file = getattr(self, "_file", None)
        if name is None:
            return f"Scenario(<invalid: construction failed>, file={file!r})"
        overrides = getattr(self, "_overrides", None)
        extra = f", overrides={overrides!r}" if overrides else ""
        return f"Scenario({name!r}, file={file!r}{extra})"


def _check_forces(forces: Iterable[Any]) -> Tuple[PythonForce, ...]:
    """The laws as a tuple, each a :class:`PythonForce`."""
    out = tuple(forces)
    for f in out:
        if not isinstance(f, PythonForce):
            raise TypeError(f"forces: expected mbsolve.PythonForce, not {type(f).__name__}")
    return out


def load(path: Union[str, "os.PathLike[str]"],
         overrides: Optional[Mapping[str, OverrideValue]] = None,
         **kwargs: OverrideValue) -> Scenario:
    """Read and validate a scenario file (TOML), with overrides as for
    ``mbsolve run --set`` (a dict of key paths and/or keywords with ``__``
    for the dot). Raises :class:`ScenarioError` naming the file and key."""
    p = os.fspath(path)
    try:
        with open(p, encoding="utf-8") as f:
            text = f.read()
    except (OSError, UnicodeDecodeError) as e:
        err = ScenarioError(f"{p}: -: cannot read the file: {e}")
        err.file, err.key, err.problem = p, "-", f"cannot read the file: {e}"
        raise err from e
    stem = os.path.splitext(os.path.basename(p))[0] or "scenario"
    return Scenario(text, p, stem, override_specs(overrides, **kwargs))


def builtin(name: str, overrides: Optional[Mapping[str, OverrideValue]] = None,
            **kwargs: OverrideValue) -> Scenario:
    """A scenario shipped inside the library: ``"fourbar"`` (the paper's
    four-bar, problem A) or ``"falling_rod"`` (problem B)."""
    return Scenario(_mbsolve.builtin_scenario(name), f"<builtin {name}>", name,
                    override_specs(overrides, **kwargs))


class Result:
    """A run's output: the columns of ``mbsolve run``'s table (same names,
    same units, same values) and its summary.

    ``result["crank.x"]`` is a column as a read-only NumPy float64 array, a view
    of one block held by the Rust side (no copy); ``result.data`` is that
    block, shape (columns, rows)."""

    __slots__ = ("_table", "data", "columns", "units", "summary", "_index", "exception")

    def __init__(self, table: Any, columns: List[str], units: List[str],
                 summary: Dict[str, Any], exception: Optional[BaseException] = None) -> None:
        self._table = table
        #: The whole table, shape (len(columns), rows), read-only float64.
        self.data: np.ndarray = np.asarray(table)
        #: Column names, in table order (``t``, ``crank.x``, ``crank.y``,
        #: ``crank.phi``, ...; bodies by name and coordinate).
        self.columns: List[str] = list(columns)
        #: Unit of each column (SI; ``""`` for none), as in ``columns.json``.
        self.units: Dict[str, str] = dict(zip(columns, units))
        #: The run summary (``mbsolve run``'s ``summary.json``) as a dict.
        self.summary: Dict[str, Any] = summary
        self._index = {c: k for k, c in enumerate(columns)}
        #: The exception a :class:`PythonForce` raised (it ended the run), or None.
        self.exception: Optional[BaseException] = exception

    @property
    def status(self) -> str:
        """``"completed"``, ``"failed"`` or ``"interrupted"``."""
        return self.summary["status"]

    @property
    def message(self) -> Optional[str]:
        """Why the run ended early (None when it completed)."""
        return self.summary.get("message")

    @property
    def warnings(self) -> List[str]:
        """The run's warnings, in order."""
        return list(self.summary.get("warnings", []))

    @property
    def t(self) -> np.ndarray:
        """Output times [s]."""
        return self["t"]

    def __len__(self) -> int:
        """Number of rows (output times)."""
        return self.data.shape[1]

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and self._column(name) is not None

    def _column(self, name: str) -> Optional[int]:
        """Index of column ``name``: its name, or a positional name of
        earlier versions (``x1``, ``phi3``) read as that body's column."""
        k = self._index.get(name)
        if k is None:
            k = _mbsolve.find_column(self.columns, name)
        return k

    def __getitem__(self, name: str) -> np.ndarray:
        """Column ``name`` (a view, no copy); ``crank.phi``, or the
        positional name of earlier versions ``phi1``."""
        k = self._column(name)
        if k is not None:
            return self.data[k]
        else:
            raise KeyError(
                f"no column {name!r}; the columns are {', '.join(self.columns[:12])}"
                + (", ..." if len(self.columns) > 12 else "")
            ) from None

    def to_dict(self) -> Dict[str, np.ndarray]:
        """Every column by name (views)."""
        return {c: self.data[k] for k, c in enumerate(self.columns)}

    def to_pandas(self) -> "Any":
        """A ``pandas.DataFrame``, one column per table column (float64);
        the units are in ``df.attrs["units"]``, the summary in
        ``df.attrs["summary"]``. Requires pandas."""
        import pandas as pd

        df = pd.DataFrame(self.data.T, columns=self.columns, copy=False)
        df.attrs["units"] = dict(self.units)
        df.attrs["summary"] = self.summary
        return df

    def to_arrow(self) -> "Any":
        """A ``pyarrow.Table`` with the run's schema: float64 fields, the
        unit of each in its field metadata ``{"unit": ...}`` (as the
        library's Arrow IPC output) and the summary as JSON in the schema
        metadata ``{"summary": ...}``. Requires pyarrow."""
        import pyarrow as pa

        fields = [pa.field(c, pa.float64(), nullable=False, metadata={"unit": self.units[c]})
                  for c in self.columns]
        schema = pa.schema(fields, metadata={"summary": json.dumps(self.summary)})
        arrays = [pa.array(self.data[k]) for k in range(len(self.columns))]
        return pa.Table.from_arrays(arrays, schema=schema)

    def reduce(self, kind: str, column: str, window: Optional[Tuple[Optional[float],
               Optional[float]]] = None, threshold: Optional[float] = None,
               direction: Optional[str] = None) -> float:
        """A reduction of a column (or an expression of columns, e.g.
        ``"rod.y - crank.y"``) over the output rows with ``t`` in
        ``window = (t_from, t_to)`` [s] (default all rows; ``None`` for an
        open end), computed by the library's metrics (``mbsolve sweep
        --metric``, ``[[metric]]``; Rust, on the result's block, no copy):
        ``"final"``, ``"min"``, ``"max"``, ``"mean"`` and ``"rms"`` (time
        averages by the trapezoidal rule), ``"crossing"`` (first time the
        value crosses ``threshold``, ``direction`` up, down or either; NaN
        if never), ``"absmax"`` (``max`` of ``abs(column)``) and
        ``"initial"`` (the first row's value in the window)."""
        k = self._column(column)
        name = self.columns[k] if k is not None else column  # else an expression
        lo, hi = window if window is not None else (None, None)
        lo = None if lo is None else float(lo)
        hi = None if hi is None else float(hi)
        if kind == "initial":
            # not a reduction: the first row of the window
            t = self.t
            rows = np.nonzero((t >= (-np.inf if lo is None else lo))
                              & (t <= (np.inf if hi is None else hi)))[0]
            if len(rows) == 0:
                raise ValueError(f"initial: no output row in the window [{lo}, {hi}]")
            return float(self[column][rows[0]])
        if kind == "absmax":
            kind, name = "max", f"abs({name})"
        try:
            return self._table.reduce(name, kind, lo, hi, threshold, direction)
        except ValueError as e:
            if k is None and f"no column '{column}'" in str(e):
                self[column]  # raises the KeyError listing the columns
            raise

    def label(self, name: str) -> str:
        """Axis label of column ``name``: the name and its unit in
        brackets (``"crank.phi [rad]"``; no brackets for unitless columns)."""
        k = self._column(name)
        name = self.columns[k] if k is not None else name
        unit = self.units.get(name, "")
        return f"{name} [{unit}]" if unit else name

    def plot(self, *columns: str, x: str = "t", ax: Any = None, logy: bool = False,
             **line_kw: Any) -> Any:
        """Plot columns against ``x`` (default ``t``) with matplotlib
        (optional dependency) and return the ``Axes``. Axis labels carry the
        units of ``columns.json``; with several columns of different units
        the y label lists each. Without columns: ``constraint_norm`` on a
        log scale. ``ax``: an existing ``Axes`` to draw on; ``logy``: a
        logarithmic y axis; ``label``: the legend entry of a single column
        (default its name); other keywords go to ``Axes.plot``."""
        try:
            import matplotlib.pyplot as plt
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError("Result.plot needs matplotlib (pip install matplotlib)") from e
        if not columns:
            columns, logy = ("constraint_norm",), True
        # by their names (a positional name of earlier versions, x1, too)
        columns = tuple(self.columns[self._column(c)] if c in self else c for c in columns)
        xs = self[x]
        if ax is None:
            _, ax = plt.subplots()
        given = line_kw.pop("label", None)
        for c in columns:
            ax.plot(xs, self[c], label=given if given is not None and len(columns) == 1 else c,
                    **line_kw)
        ax.set_xlabel(self.label(x))
        units = {self.units.get(c, "") for c in columns}
        if len(columns) == 1:
            ax.set_ylabel(self.label(columns[0]))
        elif len(units) == 1:
            u = units.pop()
            ax.set_ylabel(f"[{u}]" if u else "")
        else:
            ax.set_ylabel(", ".join(self.label(c) for c in columns))
        if len(columns) > 1:
            ax.legend()
        if logy:
            ax.set_yscale("log")
        title = self.summary.get("scenario")
        status = self.status
        ax.set_title(f"{os.path.basename(str(title)) if title else ''}"
                     + ("" if status == "completed" else f" ({status})"))
        return ax

    def __repr__(self) -> str:
        return (f"Result(status={self.status!r}, rows={len(self)}, "
                f"columns={len(self.columns)})")


from .model import Model, to_toml  # noqa: E402
from .sweeps import sweep  # noqa: E402

__all__ += ["Model", "to_toml", "sweep"]
