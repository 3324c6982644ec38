"""The quickstart notebook runs top to bottom (nbclient, a fresh kernel of
this interpreter), each cell within a time bound."""

import time

import pytest

from conftest import ROOT

NOTEBOOK = ROOT / "examples" / "notebooks" / "quickstart.ipynb"


def test_quickstart_notebook_runs():
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("matplotlib")
    nb = nbformat.read(NOTEBOOK, as_version=4)
    start = time.perf_counter()
    client = nbclient.NotebookClient(nb, timeout=300, kernel_name="python3",
                                     resources={"metadata": {"path": str(NOTEBOOK.parent)}})
    client.execute()
    wall = time.perf_counter() - start
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    text = "".join(o.get("text", "") for o in outputs if o.get("output_type") == "stream")
    # the four-bar runs, the pendulum and its scenario file printed
    assert "no stabilization: completed" in text
    assert "Baumgarte α = β = 10: completed" in text
    assert "completed 501 rows" in text and 'type = "spring"' in text
    # the sweep's table (five runs) and the figures
    html = "".join(o.get("data", {}).get("text/html", "") for o in outputs)
    assert "swing_late" in html and html.count("completed") >= 5
    images = [o for o in outputs if "image/png" in o.get("data", {})]
    assert len(images) >= 3, len(images)
    print(f"quickstart.ipynb executed in {wall:.1f} s")
