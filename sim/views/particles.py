"""Drawing a localiser's particles in the recording: after each of its scans, a thinned set of its
particles on the map, each the brighter the more likely the last scan made it, the scan's score
(its likelihood against the best any pose could give it) as a time series beside whether it is
lost, and an event where it loses the robot and finds it again.

Any estimator with `particles`, `likelihood`, `score`, `lost` and `updated` is drawn
(`bots.odometry.localiser.MonteCarloLocaliser`). As `chassis_view.ChassisLayer`, the scans are buffered and
leave with the recorder's chunk of the robot's poses (`flush`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from sim.views import palette

SHOWN = 150
"""Particles drawn per scan at most (every k-th of the set): enough to see its spread and modes,
few enough that a 300 s run's recording grows by megabytes, not hundreds."""
RADIUS_M = 0.004
"""Drawn radius of a particle (m)."""


def localisers(estimators: list[Any]) -> list[Any]:
    """The estimators that carry particles to draw."""
    return [e for e in estimators if all(hasattr(e, a) for a in ("particles", "likelihood", "score", "lost", "updated"))]


def thinned(particles: np.ndarray, likelihood: np.ndarray, rgb: palette.RGB) -> tuple[np.ndarray, np.ndarray]:
    """(k, 2) positions and (k, 3) colours of at most SHOWN of the particles: each `rgb` mixed with
    white by its likelihood over the most likely one's (pale: unlikely)."""
    every = max(1, -(-len(particles) // SHOWN))
    shown, weight = particles[::every, :2], likelihood[::every]
    top = weight.max() if len(weight) and weight.max() > 0.0 else 1.0
    strength = 0.15 + 0.85 * weight / top
    white = np.full(3, 255.0)
    colours = np.rint(white - strength[:, None] * (white - np.array(rgb, dtype=np.float64))).astype(np.uint8)
    return shown, colours


class ParticleLayer:
    """Recording of the localisers of a run, for `sim.views.recording.Recorder`: `columns(path,
    times, columns)` sends columns to every stream, `event(text, level)` notes an event now."""

    def __init__(self, columns: Callable[..., None], event: Callable[[str, str], None], robots: dict[str, list[Any]], timeline: str,
                 others: dict[str, list[str]]):  # fmt: skip
        self.columns, self.event, self.robots, self.timeline = columns, event, robots, timeline
        self.colours = {(name, e.name): palette.estimate_colour(e.name, others[name]) for name, found in robots.items() for e in found}
        self.seen: dict[tuple[str, str], float] = {}
        self.lost: dict[tuple[str, str], bool] = {}
        self.scans: dict[tuple[str, str], list[tuple[float, np.ndarray, np.ndarray, float, bool]]] = {}

    @classmethod
    def for_run(cls, columns: Callable[..., None], event: Callable[[str, str], None], logs: list[Any], timeline: str) -> ParticleLayer | None:
        """A layer for the localisers among the robots' estimators (`RobotLog.estimators`), None if none."""
        robots = {log.name: localisers(log.estimators) for log in logs}
        robots = {name: found for name, found in robots.items() if found}
        others = {log.name: log.estimate_names for log in logs}
        return cls(columns, event, robots, timeline, others) if robots else None

    def on_sample(self, world: Any, logs: list[Any]) -> None:
        """Keep each localiser's scan if it made a new one, and note where it lost or found the robot."""
        for name, found in self.robots.items():
            for localiser in found:
                key = (name, localiser.name)
                if self.seen.get(key) == localiser.updated:
                    continue
                self.seen[key] = localiser.updated
                shown, colours = thinned(localiser.particles, localiser.likelihood, self.colours[key])
                self.scans.setdefault(key, []).append((world.time, shown, colours, float(localiser.score), bool(localiser.lost)))
                if localiser.lost != self.lost.get(key, False):
                    self.lost[key] = localiser.lost
                    self.event(f"{name}: {localiser.name} " + ("lost the robot" if localiser.lost else "found the robot again"),
                               "WARN" if localiser.lost else "INFO")  # fmt: skip

    def flush(self, name: str) -> None:
        """Send robot `name`'s buffered scans."""
        import rerun as rr

        for key in [k for k in self.scans if k[0] == name]:
            scans, self.scans[key] = self.scans[key], []
            if not scans:
                continue
            times = [rr.TimeColumn(self.timeline, duration=[s[0] for s in scans])]
            base = f"world/{name}/{key[1]}"
            self.columns(f"{base}/particles", times,
                         rr.Points2D.columns(positions=np.concatenate([s[1] for s in scans]), colors=np.concatenate([s[2] for s in scans]),
                                             radii=np.full(sum(len(s[1]) for s in scans), RADIUS_M)).partition([len(s[1]) for s in scans]))  # fmt: skip
            self.columns(f"localisation/{name}/{key[1]}/scan_score", times, rr.Scalars.columns(scalars=[s[3] for s in scans]))
            self.columns(f"localisation/{name}/{key[1]}/lost", times, rr.Scalars.columns(scalars=[float(s[4]) for s in scans]))
