"""What the command line prints of other code's text (the warnings of numba, pyarrow or Dask, log
records, a traceback, rerun's own log lines) reaches the terminal escaped as ctsim's own messages
are (`sim.sanitize.Terminal`, `quiet_rerun`), and a recording or a first file that a full disk or
the file-size limit cut short is said in one line."""

from __future__ import annotations

import io
import os
import resource
import subprocess
import sys
import textwrap
from pathlib import Path

from hypothesis import given
from hypothesis import strategies as st

from bots.behaviours import make
from bots.ctbot import CTBOT
from sim import sanitize
from sim.out_files import trouble
from sim.run.loop import RobotSetup, run
from sim.views.recording.recorder import Recorder, recording_whole
from sim.world.files import load_world

ROOT = Path(__file__).resolve().parents[1]
HOSTILE = "\x1b[41mred\x1b]0;title\x07\u202eevil\x9b2J"


def _unsafe(text: str) -> list[str]:
    return [c for c in text if sanitize.escape(c, "\n\t\r") != c]


@given(st.text())
def test_the_terminal_stream_escapes_what_could_act_and_passes_the_rest(text: str) -> None:
    out = io.StringIO()
    assert sanitize.Terminal(out).write(text) == len(text)
    assert _unsafe(out.getvalue()) == []
    if not _unsafe(text):
        assert out.getvalue() == text


def _python(code: str, fsize: int | None = None, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    """`code` in a fresh interpreter (rerun reads its log settings once, at its import), under a
    file-size limit of `fsize` bytes if given."""
    def limit() -> None:
        if fsize is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))

    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], cwd=cwd, capture_output=True, text=True, timeout=600, preexec_fn=limit)


def test_a_libraries_warning_log_record_and_a_bugs_traceback_are_escaped_on_stderr() -> None:
    done = _python(f'''
        import logging, warnings
        import sim.cli.worlds
        from sim.cli.entry import main

        def hostile(args):
            warnings.warn({HOSTILE!r})
            logging.getLogger("distributed").warning({HOSTILE!r})
            raise RuntimeError({HOSTILE!r})

        sim.cli.worlds.cmd_worlds = hostile
        raise SystemExit(main(["worlds"]))
    ''')
    assert done.returncode == 1 and "this is a bug in ctsim" in done.stderr
    assert done.stderr.count("\\x1b[41mred\\x1b]0;title\\x07\\u202eevil\\x9b2J") == 3, done.stderr
    assert _unsafe(done.stderr) == []


def test_a_recording_without_reruns_footer_is_said_cut_short_and_why(tmp_path: Path) -> None:
    """rerun's file writer that stopped (a full disk, the file-size limit) says so on rerun's log
    alone, now silenced, and its flush raises or not: the recorder looks for rerun's footer at
    the file's end and names what the system says of the file (`trouble`)."""
    path = tmp_path / "run.rrd"
    recorder = Recorder(path)
    run(load_world("empty"), [RobotSetup(CTBOT, make("square", {}))], duration=0.5, observers=(recorder,))
    assert recorder.write_error is None and recording_whole(path)
    path.write_bytes(path.read_bytes()[:-100])
    assert not recording_whole(path) and not recording_whole(tmp_path / "missing.rrd")
    done = _python(f"""
        from sim.out_files import trouble
        print(trouble(__import__("pathlib").Path({str(path)!r})))
    """, fsize=path.stat().st_size)
    assert done.stdout == f"{path.stat().st_size / 1e6:.1f} MB written, and the file-size limit (ulimit -f) is {path.stat().st_size / 1e6:.1f} MB\n", done.stderr
    assert trouble(tmp_path / "gone" / "run.rrd") == "its folder is gone"


def test_rerun_is_imported_with_its_own_log_lines_off_unless_asked_for() -> None:
    """(Its Rust side writes them to the terminal past `sanitize.Terminal`, coloured: a full disk
    gave `ERROR re_log_encoding::rrd::file_sink: Failed to write log stream to FOLDER/run.rrd`
    in escape sequences, with the folder's name as it is.)"""
    quiet = _python("""
        import os
        from sim.views.recording.arrow import lazy_rerun
        lazy_rerun()
        print(os.environ["RUST_LOG"])
    """)
    assert quiet.stdout == "off\n", quiet.stderr
    asked = subprocess.run([sys.executable, "-c", "import os; from sim.cli.entry import main; main(['worlds']); print(os.environ['RUST_LOG'])"],
                           cwd=ROOT, capture_output=True, text=True, timeout=600, env={**os.environ, "RUST_LOG": "debug"})  # fmt: skip
    assert asked.stdout.endswith("debug\n"), asked.stderr


def test_a_first_file_that_meets_the_file_size_limit_is_one_line_not_a_bug(tmp_path: Path) -> None:
    out = tmp_path / "out"
    done = _python(f'''
        from sim.cli.entry import main
        raise SystemExit(main(["run", "empty", "--duration", "0.1", "--out", {str(out)!r}]))
    ''', fsize=100)
    assert done.returncode == 2, done.stderr
    assert done.stderr == f"ctsim: error: {out / 'summary.json'}: File too large\n"
