"""What `lab check` leaves besides the table: a PNG and a rerun recording of the student's
estimate against ground truth, for each public scenario that has trajectories.

Runs are recorded by the run loop's own `Recorder` (the checker passes `observers(scenario)`);
scenarios without a run (a kinematics function chained over steps) get a small recording of
their trajectories here.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sim.analysis.run_folder import RunFolder
from sim.views import palette
from sim.views.figures import write_figures
from sim.views.recording.layout import TIMELINE
from sim.world.spec import Start, WorldSpec

Tracks = dict[str, tuple[np.ndarray, np.ndarray]]
"""label -> (times (T,), poses (T, 3)); 'truth' among them."""


def observers(scenario) -> tuple:
    """A Recorder writing `run.rrd` into the scenario's folder when it is public and `lab check`
    writes artifacts; nothing otherwise."""
    from sim.views.recording.recorder import Recorder

    if scenario.out is None:
        return ()
    scenario.out.mkdir(parents=True, exist_ok=True)
    return (Recorder(RunFolder(scenario.out).recording, application_id="ctsim-lab"),)


def around(tracks: Tracks, margin: float = 0.1) -> WorldSpec:
    """An empty world just big enough for the tracks (for figures of runs without a world)."""
    points = np.concatenate([poses[:, :2] for _, poses in tracks.values()])
    low, high = points.min(axis=0) - margin, points.max(axis=0) + margin
    return WorldSpec("scenario", (*low, *high), starts=(Start(0.0, 0.0, 0.0),), floor_colour=(1.0, 1.0, 1.0))


def write_tracks_recording(path: Path, tracks: Tracks) -> Path:
    """A recording of trajectories alone: trails under world/, position errors under errors/."""
    import rerun as rr

    rec = rr.RecordingStream("ctsim-lab", send_properties=False)
    rec.save(str(path))  # (a folder of the lab's own: see write_artifacts)
    rec.log("world", rr.Transform3D(scale=(1.0, -1.0, 1.0)), static=True)
    times, truth = tracks["truth"]
    estimates = [k for k in tracks if k != "truth"]
    colours = {"truth": palette.TRUTH} | {label: palette.estimate_colour(label, estimates) for label in estimates}
    for label, (t, poses) in tracks.items():
        rec.log(f"world/{label}", rr.LineStrips2D([poses[:, :2]], colors=colours[label], radii=0.002), static=True)
        column = [rr.TimeColumn(TIMELINE, duration=t)]
        rec.send_columns(f"world/{label}/pose", column, rr.Points2D.columns(positions=poses[:, :2]).partition([1] * len(t)))
        if label != "truth":
            n = min(len(t), len(truth))
            error = np.hypot(*(poses[:n, :2] - truth[:n, :2]).T)
            rec.send_columns(f"errors/position/{label}", [rr.TimeColumn(TIMELINE, duration=t[:n])], rr.Scalars.columns(scalars=error))
    rec.flush()
    rec.disconnect()
    return path


def write(out: Path, tracks: Tracks, world: WorldSpec | None) -> list[Path]:
    """PNG figures (and, where the checker recorded no run, a recording) into `out`."""
    out.mkdir(parents=True, exist_ok=True)
    written = write_figures(world or around(tracks), {"robot": tracks}, out)
    recording = RunFolder(out).recording
    if not recording.exists():
        write_tracks_recording(recording, tracks)
    return [recording, *written]
