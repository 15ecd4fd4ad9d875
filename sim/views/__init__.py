"""The views layer: what a user looks at.

The rerun recording of a run (`recording`), PNG figures (`figures`) and the pygame-ce window for
driving by hand (`window`). It may import every layer below (kinematics, robots, world, run loop,
analysis); never the command line. rerun, matplotlib and pygame are imported where they are used,
so importing this package stays cheap.
"""

from sim.views.figures import report_run_dir, write_figures
from sim.views.recording.recorder import Recorder
from sim.views.window import play

__all__ = ["Recorder", "play", "report_run_dir", "write_figures"]
