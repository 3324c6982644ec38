"""Models built in Python with the scenario format's vocabulary.

A :class:`Model` collects the same tables a scenario file has — ``[[body]]``,
``[[joint]]`` (revolute, translational, drives), ``[[force]]`` (every type),
``[rod]``/``[[rod]]``, ``[[chain]]``, ``[[sensor]]``, ``[[state]]``
(controller states), ``[parameters]``, ``[initial]`` (with
``[[initial.joint]]``), ``[stabilization]``, ``[integrator]``, ``[time]``,
``[output]``, ``[constraints]`` — and hands them, as TOML text, to the
library's scenario reader: the validation and the error messages are the
reader's (raised as :class:`mbsolve.ScenarioError`, a ``ValueError``, naming
the element and key, e.g. ``body[1].mass``). Keys and values are those of
``docs/scenarios.md``.
"""

from __future__ import annotations

import json
import math
from typing import Any, Dict, List, Optional

import numpy as np

__all__ = ["Model", "to_toml"]


def _key(k: str) -> str:
    if k and all(c.isalnum() and c.isascii() or c in "_-" for c in k):
        return k
    return json.dumps(k, ensure_ascii=False)


def _value(v: Any, path: str) -> str:
    """A TOML value (inline) for ``v``."""
    if isinstance(v, (bool, np.bool_)):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        f = float(v)
        if math.isnan(f):
            return "nan"
        if math.isinf(f):
            return "inf" if f > 0 else "-inf"
        return repr(f)  # shortest decimal that reads back to the same bits
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # a TOML basic string
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(str(k))} = {_value(x, f'{path}.{k}')}"
                                for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_value(x, f"{path}[{i}]") for i, x in enumerate(v)) + "]"
    from . import ScenarioError

    raise ScenarioError(f"<model>: {path}: a value of type {type(v).__name__} is not a "
                        "scenario value (bool, number, string, list or dict)")


def _is_table_array(v: Any) -> bool:
    return isinstance(v, list) and len(v) > 0 and all(isinstance(x, dict) for x in v)


def _emit(table: Dict[str, Any], prefix: str, out: List[str]) -> None:
    scalars = [(k, v) for k, v in table.items()
               if not isinstance(v, dict) and not _is_table_array(v)]
    for k, v in scalars:
        out.append(f"{_key(k)} = {_value(v, prefix + k)}")
    for k, v in table.items():
        name = prefix + _key(k)
        if isinstance(v, dict):
            out.append("")
            out.append(f"[{name}]")
            _emit(v, name + ".", out)
        elif _is_table_array(v):
            for item in v:
                out.append("")
                out.append(f"[[{name}]]")
                _emit(item, name + ".", out)


def to_toml(doc: Dict[str, Any]) -> str:
    """The TOML text of a scenario document (nested dicts and lists):
    dicts become tables, lists of dicts arrays of tables, floats their
    shortest round-trip decimal."""
    out: List[str] = []
    _emit(doc, "", out)
    return "\n".join(out).lstrip("\n") + "\n"


class Model:
    """A scenario assembled in Python.

    Each method adds one element with the keys of the scenario format and
    returns the model (calls chain). Nothing is checked here: :meth:`scenario`
    (and :meth:`run`, :meth:`check`) validate through the scenario reader.

    Example (a spring pendulum)::

        m = mbsolve.Model("pendulum", gravity=(0.0, -9.81))
        m.body("bob", mass=1.0, inertia=0.01, x=0.0, y=-1.0)
        m.force("spring", body_i="ground", point_i=[0, 0], body_j="bob",
                point_j=[0, 0], stiffness=60.0, free_length=0.5)
        m.time(end=2.0).output(dt=0.01)
        r = m.run()
    """

    def __init__(self, name: Optional[str] = None, *, description: Optional[str] = None,
                 gravity: Optional[Any] = None, **top: Any) -> None:
        self._doc: Dict[str, Any] = {}
        self._forces: List[Any] = []
        if name is not None:
            self._doc["name"] = name
        if description is not None:
            self._doc["description"] = description
        if gravity is not None:
            self._doc["gravity"] = list(gravity)
        self._doc.update(top)

    def _append(self, table: str, item: Dict[str, Any]) -> "Model":
        self._doc.setdefault(table, []).append(item)
        return self

    def _table(self, table: str, keys: Dict[str, Any]) -> "Model":
        self._doc.setdefault(table, {}).update(keys)
        return self

    def set(self, **top: Any) -> "Model":
        """Top-level keys: ``formulation``, ``linear_solver``, ``gravity``, ..."""
        self._doc.update(top)
        return self

    def body(self, name: str, **keys: Any) -> "Model":
        """A ``[[body]]``: ``mass`` [kg], ``inertia`` [kg m²], ``x``, ``y``
        [m], ``phi`` [rad] or ``phi_deg``, ``vx``, ``vy``, ``omega``, ``shape``."""
        return self._append("body", {"name": name, **keys})

    def joint(self, type: str, **keys: Any) -> "Model":
        """A ``[[joint]]`` of ``type`` ``revolute``, ``translational``,
        ``drive_coordinate`` or ``drive_angle``, with its keys."""
        return self._append("joint", {"type": type, **keys})

    def force(self, type: str, **keys: Any) -> "Model":
        """A ``[[force]]`` of ``type`` ``torque``, ``force``, ``spring``,
        ``rotational_spring``, ``contact``, ``fluid``, ``expression``, ...,
        with its keys."""
        return self._append("force", {"type": type, **keys})

    def python_force(self, name: str, bodies: Any, force: Any, *, jacobian: Any = None,
                     step: Any = None) -> "Model":
        """A force law written in Python on the named bodies (a
        :class:`mbsolve.PythonForce`; see there for ``force(t, q, qd)``,
        ``jacobian`` and ``step``). Not part of :meth:`to_toml` (a scenario
        file holds no Python); :meth:`scenario` and :meth:`run` carry it."""
        from .forces import PythonForce

        self._forces.append(PythonForce(name, bodies, force, jacobian=jacobian, step=step))
        return self

    def rod(self, **keys: Any) -> "Model":
        """A flexible rod (``[[rod]]``; one rod without ``name`` is written
        as the ``[rod]`` table)."""
        return self._append("rod", dict(keys))

    def chain(self, **keys: Any) -> "Model":
        """A ``[[chain]]`` of N links."""
        return self._append("chain", dict(keys))

    def sensor(self, type: str, **keys: Any) -> "Model":
        """A ``[[sensor]]`` of ``type`` with its keys."""
        return self._append("sensor", {"type": type, **keys})

    def state(self, name: str, derivative: str, **keys: Any) -> "Model":
        """A ``[[state]]`` controller state ``z`` with ``ż = derivative`` (an
        expression of ``t``, the bodies' ``B.x`` … ``B.omega``, states and
        parameters), keys ``initial`` (z(t0), default 0) and ``unit`` (its
        output column's unit, default ``"1"``). Expressions of the model read
        it by ``name``; a run returns it as the column ``name``."""
        return self._append("state", {"name": name, "derivative": derivative, **keys})

    def parameters(self, **values: Any) -> "Model":
        """Entries of ``[parameters]``: numbers or expressions of other
        parameters, usable in every numeric field and expression."""
        return self._table("parameters", values)

    def initial(self, **keys: Any) -> "Model":
        """Keys of ``[initial]`` (``independent``, ``consistent``,
        ``perturbation``, ...)."""
        return self._table("initial", keys)

    def initial_joint(self, **keys: Any) -> "Model":
        """An ``[[initial.joint]]``: the initial state by joint coordinates."""
        self._doc.setdefault("initial", {}).setdefault("joint", []).append(dict(keys))
        return self

    def stabilization(self, **keys: Any) -> "Model":
        """Keys of ``[stabilization]`` (``alpha``, ``beta``, ...)."""
        return self._table("stabilization", keys)

    def integrator(self, **keys: Any) -> "Model":
        """Keys of ``[integrator]`` (``method``, ``rtol``, ``atol``, ...)."""
        return self._table("integrator", keys)

    def time(self, **keys: Any) -> "Model":
        """Keys of ``[time]`` (``start``, ``end``, ``output_dt`` [s])."""
        return self._table("time", keys)

    def output(self, **keys: Any) -> "Model":
        """Keys of ``[output]``."""
        return self._table("output", keys)

    def constraints(self, **keys: Any) -> "Model":
        """Keys of ``[constraints]``."""
        return self._table("constraints", keys)

    def to_dict(self) -> Dict[str, Any]:
        """The scenario document (a deep copy)."""
        return json.loads(json.dumps(self._doc))

    def to_toml(self) -> str:
        """The scenario file's text."""
        doc = dict(self._doc)
        rods = doc.get("rod")
        if isinstance(rods, list) and len(rods) == 1 and "name" not in rods[0]:
            doc["rod"] = rods[0]  # the single `[rod]` table
        return to_toml(doc)

    def scenario(self, overrides: Optional[Dict[str, Any]] = None, **kwargs: Any) -> Any:
        """The validated :class:`mbsolve.Scenario` (the scenario reader's
        checks; a :class:`mbsolve.ScenarioError` names element and key)."""
        from . import Scenario, override_specs

        name = str(self._doc.get("name", "model"))
        return Scenario(self.to_toml(), f"<model {name}>", name,
                        override_specs(overrides, **kwargs), self._forces)

    def check(self) -> Dict[str, Any]:
        """What ``mbsolve check`` reports (see :meth:`mbsolve.Scenario.check`)."""
        return self.scenario().check()

    def run(self, overrides: Optional[Dict[str, Any]] = None, *, forces: Any = (),
            progress: Any = False, **kwargs: Any) -> Any:
        """Validate and run (with the model's Python forces and ``forces``);
        returns a :class:`mbsolve.Result`. ``progress`` as for
        :meth:`mbsolve.Scenario.run`."""
        return self.scenario(overrides, **kwargs).run(forces=forces, progress=progress)

    def __repr__(self) -> str:
        n = {k: len(v) for k, v in self._doc.items() if isinstance(v, list) and k != "gravity"}
        return f"Model({self._doc.get('name')!r}, {n})"
