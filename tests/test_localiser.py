"""The Monte Carlo localiser in the run loop: it follows a c't-Bot solving the maze with realistic
noise far closer than the best dead reckoning, says when it has lost the robot, and finds a robot
kidnapped by hand (a scripted teleport) again."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bots.odometry.localiser import RECOVERY_TIME, MonteCarloLocaliser
from bots.odometry.user import load
from sim.analysis.metrics import compare_run
from sim.experiments.api import Bot, simulate
from sim.experiments.kidnap import KIDNAP_AT, ROOMS_PLACE, KeepDriving, Kidnapper, kidnapping
from sim.world.files import worlds_dir

ROOMS = worlds_dir() / "rooms.xml"


def test_the_shipped_localiser_is_an_estimator_by_name() -> None:
    assert load("localiser") is MonteCarloLocaliser


def test_the_localiser_follows_the_robot_far_closer_than_dead_reckoning() -> None:
    """30 s of the main job (solve_maze, realistic noise, seed 0): the localiser stays within
    2 cm of the truth and its ATE under 4 mm (it measured 7.6 mm and 2.3 mm; the IR sensors' noise
    is 5 mm), below the fused odometry's (20 mm, growing with every metre; over whole runs the
    localiser's is a tenth to a fiftieth of it, docs/odometry.md), it never says it is lost, and its
    covariance is a real one."""
    result = simulate("maze", noise="realistic", duration=30.0, seed=0, estimators=["localiser"])
    metrics = compare_run(result.raw)["ctbot"]
    assert metrics["localiser"].max_position_error < 0.02
    assert metrics["localiser"].ate_rmse < min(0.004, metrics["fused"].ate_rmse)
    localiser = result.raw.robots[0].estimators[-1]
    assert not localiser.lost and np.all(np.linalg.eigvalsh(localiser.covariance) > 0.0)


def test_a_robot_moved_by_hand_is_found_again() -> None:
    """Picked up and put down 10 cm further along its corridor and turned by 29 degrees: within
    1.5 s the localiser says it is lost (the scans stop fitting; measured 0.57 s); within 8 s of
    the kidnapping (measured 4.1 s) it is on the robot again and stays within 2 cm of it to the
    end, and once the robot has rolled CONFIRM metres there and the place fits the scans since the
    robot was lost (RECALL_NEAR), within 17 s (measured 13.9 s), it says so. (Where solve_maze drives the kidnapped robot decides how soon the scans tell: over
    seeds 0-15 it is found within 8 s in 12, 13 before solve_maze squared up on closed walls;
    seed 2 in both.)"""
    kidnapper = Kidnapper(by=(0.1, 0.0, 0.5))
    simulate("maze", noise="realistic", duration=KIDNAP_AT + 20.0, seed=2, estimators=["localiser"], observers=[kidnapper])
    rows = np.array(kidnapper.rows)
    assert rows[0, 1] > 0.09  # (the kidnapping happened)
    assert rows[rows[:, 0] <= 1.5, 2].any()
    assert np.all(rows[rows[:, 0] >= 8.0, 1] < 0.02)
    assert not rows[rows[:, 0] >= 17.0, 2].any()


CARRIED = [((2.76, 0.36, math.pi / 2), 4), ((0.36, 2.76, 0.0), 3), ((1.80, 1.80, math.pi), 4), ((0.84, 0.84, math.pi / 2), 4), ((1.80, 1.80, math.pi), 3), ((0.84, 0.84, math.pi / 2), 2)]
"""Kidnappings in the maze (put at (x, y m, heading rad), seed) in which the localiser before the
recall (a4a9e94, `CONFIRM` alone) said "found" on a wrong place: for 35.7 s 2.6 m off (the test's
own far corner), for 19.4 s up to 1.4 m off, for 19.3 s up to 2.1 m off, for 21.9 s up to 2.2 m off;
and the two in which the recall of 2 m, up to 3 m, did (for 3.3 s 2.2 m off, for 4.5 s 1.7 m off)."""


@pytest.mark.parametrize(("place", "seed"), CARRIED)
def test_a_robot_carried_across_the_maze_is_never_said_found_on_a_wrong_place(place: tuple[float, float, float], seed: int) -> None:
    """Carried across the maze 30 s into the main job: within 1.5 s the localiser says it is lost,
    and in the minute after it never says otherwise while its estimate is more than 0.1 m off:
    FOUND_SPREAD, the widest spread the search may end with. A place found again is followed
    within 2 cm; the wrong places the search ended on in docs/odometry.md's kidnappings were
    0.19-2.6 m off, so 0.1 m tells the two apart with room either way. (Finding it again is not
    promised: two forward IR sensors see little of a maze whose corridors look alike.)"""
    kidnapper = Kidnapper(at=place)
    simulate("maze", noise="realistic", duration=KIDNAP_AT + 60.0, seed=seed, estimators=["localiser"], observers=[kidnapper])
    rows = np.array(kidnapper.rows)
    assert rows[0, 1] > 0.3 and rows[rows[:, 0] <= 1.5, 2].any()
    said_found = rows[(rows[:, 0] > 1.5) & (rows[:, 2] == 0)]
    assert np.all(said_found[:, 1] < 0.1)


FOUND_AGAIN = [((0.36, 2.76, 0.0), 4), ((2.76, 0.36, math.pi / 2), 1), ((2.52, 2.28, -math.pi / 2), 3)]
"""Kidnappings in the maze (put at, seed) of docs/odometry.md's table: one in which the localiser
said found 2.5 m off while its global search was tried out, one found at once before it, and one
the localiser before it did not find within the minute."""


@pytest.mark.slow
def test_a_robot_carried_across_the_maze_is_found_again_within_the_stated_time() -> None:
    """The localiser's stated time (bots/odometry/localiser.py, docs/odometry.md) on three
    kidnappings, the robot driving solve_maze on (`KeepDriving`): said lost within 1.5 s, found
    again, `lost` cleared on the robot, within RECOVERY_TIME s, and never said found while 0.1 m or more
    off."""
    for place, seed in FOUND_AGAIN:
        run = kidnapping(place, seed, after=RECOVERY_TIME)
        assert run["lost"] <= 1.5 and run["found"] <= RECOVERY_TIME and run["wrong"] == 0, run


def test_the_recording_shows_the_particles_and_the_scan_score(tmp_path) -> None:  # noqa: ANN001
    """After every scan the recording holds at most 150 of the particles on the map, the scan's
    score and the lost flag, and the blueprint plots the two beside the errors."""
    import rerun.chunk

    path = tmp_path / "run.rrd"
    simulate("maze", noise="realistic", duration=2.0, seed=0, estimators=["localiser"], record=path)
    rows: dict[str, list] = {}
    for chunk in rerun.chunk.RrdReader(path).stream().to_chunks():
        if not chunk.is_static:
            batch = chunk.to_record_batch()
            for name in ("Points2D:positions", "Scalars:scalars"):
                if name in batch.schema.names:
                    rows.setdefault(chunk.entity_path, []).extend(batch.column(name).to_pylist())
    scans = rows["/world/ctbot/localiser/particles"]
    assert len(scans) >= 30 and all(0 < len(points) <= 150 for points in scans)  # 2 s of scans every 50 ms while it moves
    assert len(rows["/localisation/ctbot/localiser/scan_score"]) == len(scans) == len(rows["/localisation/ctbot/localiser/lost"])
    (store,) = rerun.chunk.RrdReader(path).blueprints()
    origins = [chunk.to_record_batch().column("ViewBlueprint:space_origin").to_pylist()[-1][0]
               for chunk in rerun.chunk.RrdReader(path).stream(store=store).to_chunks()
               if "ViewBlueprint:space_origin" in chunk.to_record_batch().schema.names]  # fmt: skip
    assert "/localisation/ctbot" in origins


def test_a_robot_carried_across_the_rooms_parcours_is_found_again() -> None:
    """Carried 3 m across worlds/rooms.xml (a parcours whose rooms differ, unlike the maze's
    corridors) and turned to face west, seed 3, solve_maze driving on (`KeepDriving`): within 1.5 s
    the localiser says it is lost (measured 1.12 s), and from 57 s after the kidnapping on it stays
    within 2 cm of the robot and says it found it (measured from 52.3 s on, once 3.5 m of scans,
    RECALL, fit the place, two global searches in a row ended on it, and no other place fitted:
    `_rivals`). Seed 3 is one of ten measured (docs/odometry.md)."""
    kidnapper = Kidnapper(at=ROOMS_PLACE)
    simulate(str(ROOMS), Bot(KeepDriving()), noise="realistic", duration=KIDNAP_AT + 64.0, seed=3, estimators=["localiser"], observers=[kidnapper])
    rows = np.array(kidnapper.rows)
    assert rows[0, 1] > 2.5 and rows[rows[:, 0] <= 1.5, 2].any()
    later = rows[rows[:, 0] >= 57.0]
    assert len(later) > 600 and not later[:, 2].any() and np.all(later[:, 1] < 0.02)


@pytest.mark.parametrize("arguments", [[], ["six", "0", "1"], ["five", "a", "2"], ["five", "3", "1"]])
def test_the_kidnapping_measurement_refuses_wrong_arguments_in_a_line(arguments, capsys) -> None:  # noqa: ANN001
    """`python -m sim.experiments.kidnap` with a wrong argument: argparse's usage line naming it and
    exit status 2, before any run."""
    from sim.experiments.kidnap import main

    with pytest.raises(SystemExit) as ended:
        main(arguments)
    assert ended.value.code == 2 and "error:" in capsys.readouterr().err
