"""Type stubs of the Rust extension ``mbsolve._mbsolve`` (internal; use the
``mbsolve`` package's functions)."""

from typing import Any, Callable, List, Optional, Sequence, Tuple

__version__: str

class ScenarioError(ValueError):
    """An invalid scenario, override or model; ``file``, ``key`` (dotted key
    path) and ``problem`` say where and what."""

    file: str
    key: str
    problem: str

class RunError(RuntimeError):
    """A run that could not start."""

class Table:
    """A run's table, column-major float64, viewed by NumPy without a copy."""

    @property
    def __array_interface__(self) -> dict: ...
    @property
    def shape(self) -> Tuple[int, int]: ...
    def reduce(self, quantity: str, kind: str, t_from: Optional[float] = None,
               t_to: Optional[float] = None, threshold: Optional[float] = None,
               direction: Optional[str] = None) -> float:
        """A column or an expression of columns reduced by the library's
        metrics (final, min, max, mean, rms, crossing) over the rows with
        t_from <= t <= t_to."""

def find_column(names: List[str], name: str) -> Optional[int]:
    """Index of column ``name`` among ``names``, or of the column its
    positional name of earlier versions (``x1``, ``phi3``) stands for."""

def validate(text: str, file: str, stem: str, overrides: List[str]) -> str:
    """Parse and validate; returns the scenario's name."""

def check_json(text: str, file: str, stem: str, overrides: List[str]) -> str:
    """What ``mbsolve check`` reports, as JSON text."""

ForceSpec = Tuple[str, List[str], Callable[..., Any], Optional[Callable[..., Any]],
                  Optional[Callable[..., Any]]]

def run(
    text: str, file: str, stem: str, overrides: List[str], check_signals: bool = True,
    forces: Sequence[ForceSpec] = (), progress: Optional[Callable[[float, float, float], Any]] = None,
    one_thread: bool = False,
) -> Tuple[Table, List[str], List[str], str, Optional[BaseException]]:
    """Run: (table, column names, units, summary JSON, the first exception
    a Python force raised)."""

def builtin_scenario(name: str) -> str:
    """The TOML text of a shipped scenario (``fourbar``, ``falling_rod``)."""

def _panic_for_test() -> None: ...
