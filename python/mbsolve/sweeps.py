"""Sweeps: one scenario run for many sets of overrides, with metrics per
run, as a ``pandas.DataFrame`` (one row per run, in the order of the
parameter grid).

Locally the runs go side by side on a thread pool (each run releases the
GIL and runs on one thread, as ``mbsolve sweep`` does); given a
``dask.distributed`` ``Client``, the same runs are spread over its workers.
Each run and its metrics are computed by the same function either way, so
the two give the same table.
"""

from __future__ import annotations

import itertools
import math
import os
import re
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

#: A metric: a Python function of the :class:`mbsolve.Result`, a named
#: reduction as text (``"rms(coupler.phi, 1.0, 2.0)"``, ``"final(crank.x)"``)
#: or a tuple ``("rms", "coupler.phi", (1.0, 2.0))``, or a key of the run's summary
#: (``"max_constraint_norm"``, ``"wall_s"``).
Metric = Union[str, Tuple[Any, ...], Callable[[Any], Any]]

REDUCTIONS = ("final", "initial", "max", "min", "absmax", "mean", "rms")
"""The named reductions: the library's metrics (``mbsolve.output.metrics``:
final, max, min, mean and rms as time averages), ``absmax`` = max of abs,
and ``initial`` (the window's first row)."""

_CALL = re.compile(r"^\s*(\w+)\s*\(\s*([^,()]+?)\s*(?:,\s*([^,()]*?)\s*,\s*([^,()]*?)\s*)?\)\s*$")


def _bound(text: str, spec: str) -> Optional[float]:
    text = text.strip()
    if text in ("", "None", "none"):
        return None
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"metric {spec!r}: window bound {text!r} is not a number") from None


def parse_metric(spec: Metric) -> Metric:
    """A metric in canonical form: a callable, a summary key (str) or a
    reduction ``(kind, column, (t_from, t_to))``; raises ``ValueError`` for
    a malformed one."""
    if callable(spec):
        return spec
    if isinstance(spec, tuple):
        if len(spec) not in (2, 3) or spec[0] not in REDUCTIONS:
            raise ValueError(f"metric {spec!r}: expected (reduction, column[, (t_from, t_to)]) "
                             f"with a reduction of {', '.join(REDUCTIONS)}")
        window = spec[2] if len(spec) == 3 else (None, None)
        return (spec[0], str(spec[1]), tuple(window))
    if isinstance(spec, str):
        m = _CALL.match(spec)
        if m is None:
            return spec  # a summary key
        kind, column, lo, hi = m.groups()
        if kind not in REDUCTIONS:
            raise ValueError(f"metric {spec!r}: unknown reduction {kind!r} "
                             f"({', '.join(REDUCTIONS)})")
        window = (None, None) if lo is None else (_bound(lo, spec), _bound(hi, spec))
        return (kind, column, window)
    raise TypeError(f"metric {spec!r}: expected a function, a reduction or a summary key")


def evaluate(result: Any, name: str, metric: Metric) -> Any:
    """The value of one (canonical) metric for a result. A failed or
    interrupted run's reductions cover the rows it computed; a reduction
    over an empty window gives NaN."""
    if callable(metric):
        return metric(result)
    if isinstance(metric, tuple):
        kind, column, window = metric
        if len(result) == 0:
            return math.nan
        try:
            return result.reduce(kind, column, window)
        except ValueError as e:
            if "no output row" in str(e):
                return math.nan
            raise
    if metric not in result.summary:
        raise KeyError(f"metric {name!r}: not a reduction such as 'max(crank.x)' nor a summary key "
                       f"(summary keys: {', '.join(sorted(result.summary))})")
    return result.summary[metric]


def grid(params: Union[Mapping[str, Sequence[Any]], Sequence[Mapping[str, Any]]]
         ) -> List[Dict[str, Any]]:
    """The runs' overrides: the product of ``{key: values}`` (first key
    slowest, as ``mbsolve sweep --param``), or a list of override dicts
    taken as given."""
    if isinstance(params, Mapping):
        keys = list(params)
        values = []
        for k in keys:
            v = params[k]
            if isinstance(v, (str, bytes)) or not hasattr(v, "__iter__"):
                raise TypeError(f"params[{k!r}]: expected a sequence of values, "
                                f"not {type(v).__name__}")
            values.append(list(v))
        return [dict(zip(keys, combo)) for combo in itertools.product(*values)]
    return [dict(p) for p in params]


def _metrics(metrics: Union[None, Mapping[str, Metric], Sequence[Metric]]
             ) -> List[Tuple[str, Metric]]:
    if metrics is None:
        return []
    if isinstance(metrics, Mapping):
        items = list(metrics.items())
    else:
        items = []
        for m in metrics:
            if not isinstance(m, (str, tuple)):
                name = getattr(m, "__name__", None)
                if not name:
                    raise TypeError("a metric function in a list needs a __name__; "
                                    "give metrics as a dict {name: function}")
                items.append((name, m))
            else:
                items.append((m if isinstance(m, str) else "_".join(map(str, m[:2])), m))
    return [(str(n), parse_metric(m)) for n, m in items]


def run_one(scenario: Any, overrides: Dict[str, Any], metrics: List[Tuple[str, Metric]],
            one_thread: bool = True) -> Dict[str, Any]:
    """One run of a sweep and its metrics, as a row: the overrides, then
    ``status``, ``message``, ``rows``, then the metrics. The unit of work of
    the local pool and of a Dask worker alike."""
    r = scenario.run(overrides, _one_thread=one_thread)
    row: Dict[str, Any] = dict(overrides)
    row["status"] = r.status
    row["message"] = r.message
    row["rows"] = len(r)
    for name, m in metrics:
        row[name] = evaluate(r, name, m)
    return row


def sweep(scenario: Any, params: Union[Mapping[str, Sequence[Any]], Sequence[Mapping[str, Any]]],
          metrics: Union[None, Mapping[str, Metric], Sequence[Metric]] = None, *,
          workers: Optional[int] = None, client: Any = None) -> Any:
    """Run ``scenario`` (a :class:`mbsolve.Scenario`, a :class:`mbsolve.Model`
    or a path) once per set of overrides and return a ``pandas.DataFrame``:
    one row per run in the order of ``params`` (``{key path: values}``,
    product with the first key slowest, or a list of override dicts), with
    the overrides, ``status``, ``message``, ``rows`` and one column per
    metric.

    ``metrics``: ``{name: metric}`` or a list; a metric is a function of the
    :class:`mbsolve.Result`, a named reduction ``"final(crank.x)"``,
    ``"max(constraint_norm)"``, ``"rms(coupler.phi, 1.0, 2.0)"`` (over
    ``1.0 <= t <= 2.0``; kinds: final, initial, max, min, absmax, mean,
    rms), a tuple ``("rms", "coupler.phi", (1.0, 2.0))``, or a summary key such as
    ``"max_constraint_norm"``.

    ``workers``: local threads (default: the CPU count). ``client``: a
    ``dask.distributed.Client``: the runs become Dask tasks on its workers
    (the scenario and metric functions are pickled with cloudpickle); the
    table is the same as the local one. A failed run is a row with its
    status, not an exception; an invalid override raises
    :class:`mbsolve.ScenarioError` before any run starts."""
    import pandas as pd

    from . import Scenario, load

    if isinstance(scenario, (str, os.PathLike)):
        scenario = load(scenario)
    elif hasattr(scenario, "scenario") and not isinstance(scenario, Scenario):
        scenario = scenario.scenario()  # a Model
    if not isinstance(scenario, Scenario):
        raise TypeError(f"sweep: expected a Scenario, Model or path, not {type(scenario).__name__}")
    runs = grid(params)
    ms = _metrics(metrics)
    # every override is validated here, so a typo fails before any run
    for o in runs:
        scenario.with_overrides(o)
    if client is not None:
        futures = client.map(run_one, [scenario] * len(runs), runs, [ms] * len(runs),
                             pure=False)
        rows = client.gather(futures)
    elif len(runs) <= 1 or workers == 1:
        rows = [run_one(scenario, o, ms, one_thread=False) for o in runs]
    else:
        n = min(workers or os.cpu_count() or 1, len(runs))
        with ThreadPoolExecutor(max_workers=n) as pool:
            rows = list(pool.map(lambda o: run_one(scenario, o, ms), runs))
    return pd.DataFrame(rows, columns=_columns(runs, ms))


def _columns(runs: List[Dict[str, Any]], metrics: List[Tuple[str, Metric]]) -> List[str]:
    keys: List[str] = []
    for o in runs:
        keys.extend(k for k in o if k not in keys)
    return keys + ["status", "message", "rows"] + [n for n, _ in metrics]
