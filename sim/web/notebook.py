"""A run's recording inline in Jupyter: rerun's notebook widget (the optional `rerun-notebook`,
`pip install "ctsim[notebook]"`) with the recording and its blueprint, the layout of the native
viewer. The data reaches the widget through the kernel, so it works on a remote Jupyter too.

    result = simulate("maze", duration=20, record="maze.rrd")
    result                     # the summary table and figures (Result._repr_html_)
    viewer(result)             # the recording, to scrub through
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from sim.web.serve import recording_of


def viewer(recording: Any, width: int | str = "auto", height: int = 640) -> Any:
    """rerun's notebook viewer showing `recording`: a run folder, a .rrd file, or a result of
    `simulate(..., record=...)`. Raises rerun's own message where rerun-notebook is missing."""
    import rerun as rr
    from rerun.chunk import RrdReader
    from rerun.notebook import Viewer

    if hasattr(recording, "recording"):
        if recording.recording is None:
            raise ValueError("this result has no recording: run simulate(..., record='run.rrd') to make one")
        recording = recording.recording
    path = recording_of(Path(recording))
    stream = rr.RecordingStream("ctsim", recording_id=RrdReader(path).recordings()[0].recording_id, send_properties=False)
    widget = Viewer(width=width, height=height, recording=stream)
    stream.log_file_from_path(path)  # the recording and its blueprint, as the file has them
    stream.flush()
    return widget
