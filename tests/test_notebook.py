"""Notebooks: a result shows itself as HTML (table, figures, facts); the inline rerun viewer gets
the recording and its blueprint; a lab exercise written as a notebook is graded from its solution
cell like a file, with the same hints; the example notebook in docs/ and a lab notebook run
headless (nbclient, the `notebook` extra: those tests skip where it is missing)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from sim.cli.entry import main

ROOT = Path(__file__).resolve().parents[1]
LAB = ROOT / "tests" / "lab" / "ex2"
CELL_LIMIT_S = 900
"""Per cell: the first run in a fresh kernel may compile the kernels (a hang guard, never a verdict)."""


def _execute(path: Path, folder: Path) -> dict:
    """Run a notebook headless in `folder`, as Jupyter would; the notebook with its outputs."""
    nbformat = pytest.importorskip("nbformat", reason="the notebook extra is not installed (pip install -e '.[notebook]')")
    nbclient = pytest.importorskip("nbclient", reason="the notebook extra is not installed (pip install -e '.[notebook]')")
    pytest.importorskip("ipykernel", reason="the notebook extra is not installed (pip install -e '.[notebook]')")
    notebook = nbformat.read(path, as_version=4)
    nbformat.validate(notebook)
    nbclient.NotebookClient(notebook, timeout=CELL_LIMIT_S, kernel_name="python3", resources={"metadata": {"path": str(folder)}}).execute()
    return notebook


def _text(cell: dict) -> str:
    return "".join(out.get("text", "") for out in cell["outputs"] if out["output_type"] == "stream")


def _public_rows(table: str) -> str:
    """The table down to the hidden scenarios: the public rows and their hints (the hidden ones
    are drawn from a fresh seed each check)."""
    lines = table.splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("scenario "))
    last = next(i for i, line in enumerate(lines) if line.startswith("hidden 1"))
    return "\n".join(" ".join(line.split()) for line in lines[first:last])  # columns as wide as the widest hidden row


def _with_solution(notebook: Path, code: str) -> None:
    document = json.loads(notebook.read_text())
    (cell,) = [c for c in document["cells"] if "solution" in c["metadata"].get("tags", [])]
    cell["source"] = "".join(cell["source"]).splitlines(keepends=True)[:1] + [code]  # keep %%writefile
    notebook.write_text(json.dumps(document))


def test_a_result_shows_its_table_figures_and_facts_as_html(tmp_path):
    from sim.experiments import Bot, simulate

    result = simulate("maze", Bot("solve_maze"), duration=1, seed=1, record=tmp_path / "r.rrd")
    html = result._repr_html_()
    assert "<table class='ctsim'>" in html and "solve_maze" in html
    for estimate, errors in result.robots[0].metrics.items():  # each estimate's row, as `ctsim run` rounds it
        assert f"{estimate}</td>" in html and f"<td>{errors['ate_rmse']:.4f}</td>" in html
    assert html.count("src='data:image/png;base64,") == 2  # trajectories and errors, inside the page
    assert "seed</td><td class='text'>1</td>" in html
    assert result.recording == tmp_path / "r.rrd"


def test_the_inline_viewer_gets_the_recording_and_its_blueprint(tmp_path, monkeypatch):
    rerun_notebook = pytest.importorskip("rerun_notebook", reason="rerun-notebook (the notebook extra) is not installed")
    import time

    from rerun.chunk import RrdReader

    from sim.experiments import Bot, simulate
    from sim.web.notebook import viewer

    result = simulate("maze", Bot("solve_maze"), duration=1, seed=1, record=tmp_path / "r.rrd")
    sent: list[bytes] = []
    monkeypatch.setattr(rerun_notebook.Viewer, "send_rrd", lambda self, data: sent.append(bytes(data)))
    viewer(result)

    def stores() -> set[str]:  # each message the widget gets is a small .rrd stream of its own
        kinds = set()
        for i, data in enumerate(list(sent)):
            piece = tmp_path / f"piece{i}.rrd"
            piece.write_bytes(data)
            reader = RrdReader(piece)
            kinds |= {f"{s.kind} {s.recording_id}" for s in [*reader.recordings(), *reader.blueprints()]}
        return kinds

    original = RrdReader(tmp_path / "r.rrd")
    expected = {f"{s.kind} {s.recording_id}" for s in [*original.recordings(), *original.blueprints()]}
    deadline = time.monotonic() + 300
    while stores() != expected and time.monotonic() < deadline:
        time.sleep(0.5)  # the file is read on rerun's own thread
    assert stores() == expected  # the run and the blueprint of the native viewer


def test_a_lab_notebook_is_graded_from_its_solution_cell(tmp_path, capsys):
    assert main(["lab", "start", "2", str(tmp_path), "--notebook"]) == 0
    notebook = tmp_path / "exercise2.ipynb"
    document = json.loads(notebook.read_text())
    kinds = [c["cell_type"] for c in document["cells"]]
    assert kinds[0] == "markdown" and kinds[-2:] == ["code", "code"]  # the sheet, the solution, the check
    _with_solution(notebook, (LAB / "reference.py").read_text())
    capsys.readouterr()
    assert main(["lab", "check", "2", str(notebook), "--out", str(tmp_path / "out")]) == 0
    capsys.readouterr()
    _with_solution(notebook, (LAB / "euler.py").read_text())
    assert main(["lab", "check", "2", str(notebook), "--out", str(tmp_path / "out")]) == 1
    from_notebook = capsys.readouterr().out
    (tmp_path / "forward.py").write_text((LAB / "euler.py").read_text())
    assert main(["lab", "check", "2", str(tmp_path / "forward.py"), "--out", str(tmp_path / "out")]) == 1
    from_file = capsys.readouterr().out
    assert "Euler" in _public_rows(from_file)
    assert _public_rows(from_notebook) == _public_rows(from_file)


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        ("{not json", "not a notebook"),
        ("[1, 2]", "not a notebook (no cells)"),
        ('{"cells": []}', "0 code cells tagged 'solution'"),
        ('{"cells": [{"cell_type": "code", "metadata": ["solution"], "source": "x = 1"}, 7]}', "0 code cells tagged 'solution'"),
        ('{"cells": [' + ", ".join(['{"cell_type": "code", "metadata": {"tags": ["solution"]}, "source": "x = 1"}'] * 2) + "]}", "2 code cells tagged"),
    ],
)
def test_a_notebook_without_a_solution_cell_is_refused_in_one_line(tmp_path, capsys, content, reason):
    notebook = tmp_path / "exercise2.ipynb"
    notebook.write_text(content)
    assert main(["lab", "check", "2", str(notebook)]) == 2
    err = capsys.readouterr().err
    assert reason in err and str(notebook) in err and err.count("\n") == 1, err


def test_a_wrong_solution_in_the_notebook_gets_the_hint_of_the_file(tmp_path, capsys):
    assert main(["lab", "start", "2", str(tmp_path), "--notebook"]) == 0
    notebook = tmp_path / "exercise2.ipynb"
    _with_solution(notebook, (LAB / "euler.py").read_text())
    executed = _execute(notebook, tmp_path)
    shown = _text(executed.cells[-1])
    assert (tmp_path / "forward.py").read_text() == (LAB / "euler.py").read_text()  # the cell wrote the graded file
    capsys.readouterr()
    assert main(["lab", "check", "2", str(tmp_path / "forward.py"), "--out", str(tmp_path / "out")]) == 1
    in_terminal = capsys.readouterr().out
    assert "Euler" in _public_rows(shown)
    assert _public_rows(shown) == _public_rows(in_terminal)


def test_the_example_notebook_runs_headless(tmp_path):
    executed = _execute(ROOT / "docs" / "example.ipynb", tmp_path)
    shown = [out for cell in executed.cells if cell.cell_type == "code" for out in cell.outputs]
    errors = [out for out in shown if out["output_type"] == "error"]
    assert not errors, errors
    html = "".join(out.get("data", {}).get("text/html", "") for out in shown)
    assert "<table class='ctsim'>" in html and len(re.findall("data:image/png;base64,", html)) == 2
    assert (tmp_path / "example.rrd").is_file()
