"""Hostile input, one test per case of issue #26: files, options, controllers, output folders and
signals that once crashed, hung or lost a run now end in one clear line and a documented status,
with what was simulated kept. Each test builds its hostile file or command itself."""

from __future__ import annotations

import pytest

from sim.cli import main
from sim.experiments import Serial, load_results, sweep

STOPS_ONCE = '''
from pathlib import Path
from bots.commands import Twist

MARKER = Path(__file__).with_suffix(".stopped")

class StopsOnce:
    """Acts as Ctrl-C in its second step, the first time it runs."""
    def step(self, t, readings):
        if t > 0 and not MARKER.exists():
            MARKER.touch()
            raise KeyboardInterrupt
        return Twist(0.1, 0.0)
'''


def test_an_interrupted_sweep_keeps_no_row_of_the_run_it_cut_and_redoes_it_on_resume(tmp_path):
    controller = tmp_path / "stops.py"
    controller.write_text(STOPS_ONCE)
    spec = {"base": {"duration": 0.05, "world": "empty", "controller": f"{controller}:StopsOnce"}, "axes": {"seed": [0, 1]}}
    with pytest.raises(KeyboardInterrupt):
        sweep(spec, tmp_path / "out", Serial(), progress=False)
    assert len(load_results(tmp_path / "out")) == 0  # the cut run is not a row
    table = sweep(spec, tmp_path / "out", Serial(), progress=False)
    assert len(table) == 2 and (table["reason"] == "duration").all()


def test_a_sweep_of_a_million_runs_is_refused_at_once_with_the_limit(tmp_path, capsys):
    spec = tmp_path / "big.toml"
    spec.write_text("[axes]\nseed = [" + ", ".join(map(str, range(1000))) + "]\n\"params.speed_m_s\" = [" + ", ".join(f"{0.1 + i * 1e-4:.4f}" for i in range(1000)) + "]\n")
    assert main(["sweep", str(spec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "1,000,000 runs" in err and "100,000" in err and err.count("\n") == 1
