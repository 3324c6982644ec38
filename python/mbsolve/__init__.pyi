"""Type stubs of the ``mbsolve`` package (the public API; the docstrings of
the package itself say what each does)."""

import os
from typing import (Any, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple,
                    Union)

import numpy as np

from ._mbsolve import RunError as RunError
from ._mbsolve import ScenarioError as ScenarioError
from ._progress import ProgressArg
from .forces import PythonForce as PythonForce
from .model import Model as Model
from .model import to_toml as to_toml
from .sweeps import Metric

__version__: str
__all__: List[str]

OverrideValue = Union[bool, int, float, str, List[Any], Tuple[Any, ...]]
Overrides = Optional[Mapping[str, OverrideValue]]
Window = Optional[Tuple[Optional[float], Optional[float]]]

def override_specs(overrides: Overrides = None, **kwargs: OverrideValue) -> List[str]:
    """The ``--set KEY=VALUE`` strings of a dict of key paths and keywords
    (``__`` for the dot)."""

class Scenario:
    """A validated scenario: TOML text, file, overrides and Python forces."""

    def __init__(self, text: str, file: str = "<string>", stem: str = "scenario",
                 overrides: Iterable[str] = (), forces: Iterable[PythonForce] = ()) -> None: ...
    @classmethod
    def from_toml(cls, text: str, overrides: Overrides = None, *, name: str = "scenario",
                  file: str = "<string>", **kwargs: OverrideValue) -> "Scenario":
        """A scenario from TOML text."""
    @property
    def name(self) -> str: ...
    @property
    def text(self) -> str: ...
    @property
    def file(self) -> str: ...
    @property
    def overrides(self) -> List[str]: ...
    @property
    def forces(self) -> List[PythonForce]: ...
    def with_overrides(self, overrides: Overrides = None,
                       **kwargs: OverrideValue) -> "Scenario":
        """A new scenario with more overrides."""
    def with_forces(self, *forces: PythonForce) -> "Scenario":
        """A new scenario with more Python forces."""
    def check(self) -> Dict[str, Any]:
        """What ``mbsolve check`` reports, as a dict."""
    def run(self, overrides: Overrides = None, *, forces: Iterable[PythonForce] = (),
            progress: ProgressArg = False, **kwargs: OverrideValue) -> "Result":
        """Run (GIL released) and return the :class:`Result`."""

class Result:
    """A run's table (NumPy views) and summary."""

    data: np.ndarray
    columns: List[str]
    units: Dict[str, str]
    summary: Dict[str, Any]
    exception: Optional[BaseException]
    def __init__(self, table: Any, columns: List[str], units: List[str],
                 summary: Dict[str, Any], exception: Optional[BaseException] = None) -> None: ...
    @property
    def status(self) -> str:
        """``"completed"``, ``"failed"``, ``"diverged"`` or ``"interrupted"``."""
    @property
    def message(self) -> Optional[str]: ...
    @property
    def warnings(self) -> List[str]: ...
    @property
    def t(self) -> np.ndarray: ...
    def __len__(self) -> int: ...
    def __contains__(self, name: object) -> bool: ...
    def __getitem__(self, name: str) -> np.ndarray: ...
    def to_dict(self) -> Dict[str, np.ndarray]: ...
    def to_pandas(self) -> Any:
        """A ``pandas.DataFrame`` (units in ``attrs``)."""
    def to_arrow(self) -> Any:
        """A ``pyarrow.Table`` (units in the field metadata)."""
    def reduce(self, kind: str, column: str, window: Window = None,
               threshold: Optional[float] = None, direction: Optional[str] = None) -> float:
        """final, min, max, mean, rms (time averages), crossing, absmax or
        initial of a column or an expression of columns over a window."""
    def label(self, name: str) -> str:
        """``"name [unit]"``."""
    def plot(self, *columns: str, x: str = "t", ax: Any = None, logy: bool = False,
             **line_kw: Any) -> Any:
        """Plot columns with matplotlib; returns the Axes."""

def load(path: Union[str, "os.PathLike[str]"], overrides: Overrides = None,
         **kwargs: OverrideValue) -> Scenario:
    """Read and validate a scenario file."""

def builtin(name: str, overrides: Overrides = None, **kwargs: OverrideValue) -> Scenario:
    """``"fourbar"`` or ``"falling_rod"``, shipped inside the library."""

def sweep(scenario: Union[Scenario, Model, str, "os.PathLike[str]"],
          params: Union[Mapping[str, Sequence[Any]], Sequence[Mapping[str, Any]]],
          metrics: Union[None, Mapping[str, Metric], Sequence[Metric]] = None, *,
          workers: Optional[int] = None, client: Any = None) -> Any:
    """One row per run (a ``pandas.DataFrame``), locally or on a Dask client."""
