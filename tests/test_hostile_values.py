"""Hostile values and files, round two: numbers at the edges of floating point and of integers,
files that are not files, byte-order marks, worlds within the limits that once took hours to
check, and what a world file says that a loader must not pass over in silence. Every refusal is
one line naming the file and line or the option."""

from __future__ import annotations

import math
import os
import shutil
import sys

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bots.schema import MAX_DIGITS, TINY, Field, FileError, Problem, parse_number
from bots.spec import load_robot
from sim.world.files import load_world, world_warnings
from sim.world.files.geometry import Budget, Near

ROBOT = 'name = "b"\nwheel_diameter = 0.0567\ntrack_width = 0.0972\nbody_radius = 0.06\n'
POSITIVE = Field("number", "m", 0.0, 10.0, above=True)

subnormals = st.floats(min_value=-TINY, max_value=TINY, allow_subnormal=True, exclude_min=True, exclude_max=True).filter(lambda v: v != 0)


@given(subnormals)
def test_a_subnormal_number_is_refused_by_every_number_field(value):
    for field, given_ in ((POSITIVE, abs(value)), (Field("number", "m", -1.0, 1.0), value), (Field("pair", "m", -1.0, 1.0), [0.5, value])):
        with pytest.raises(Problem, match="subnormal number, too small to compute with$"):
            field.check(given_)


@given(st.one_of(st.just(math.nan), st.just(math.inf), st.just(-math.inf), st.floats(min_value=1e300), st.integers(min_value=10**20, max_value=10**4000)))
def test_nan_infinities_and_huge_numbers_are_refused_by_name(value):
    with pytest.raises(Problem) as refused:
        POSITIVE.check(value)
    assert refused.value.message.startswith("must be a number (m) greater than 0 and at most 10, not ")
    assert len(refused.value.message) < 120  # (a 4,000-digit number is said by its size, not printed)


def test_negative_zero_is_kept_as_zero():
    value = Field("number", "rad", -1.0, 1.0).check(-0.0)
    assert value == 0.0 and math.copysign(1.0, value) == 1.0


@given(st.integers(min_value=-(10**60), max_value=10**60))
def test_any_integer_is_compared_exactly_and_never_overflows(value):
    field = Field("number", "", -1e4, 1e4)
    if -1e4 <= value <= 1e4:
        assert field.check(value) == float(value)
    else:
        with pytest.raises(Problem):
            field.check(value)


@pytest.mark.parametrize("text, message", [("9" * 5000, "5,000 digits"), ("nan", "finite"), ("inf", "finite"), ("1e999", "finite"), ("x", "a number")])
def test_an_option_number_is_refused_with_the_reason(text, message):
    with pytest.raises(ValueError, match=message):
        parse_number(text)


def test_forty_digits_are_the_most_an_option_number_has():
    assert parse_number("1" * MAX_DIGITS, int) == int("1" * MAX_DIGITS)
    with pytest.raises(ValueError, match="41 digits"):
        parse_number("1" * (MAX_DIGITS + 1), int)


@pytest.mark.parametrize(
    "extra, line, message",
    [
        ("mass = 5e-324\n", 5, "mass: must be a number (kg) at least 0.001 and at most 1,000, not 5e-324"),
        ("mass = 1e-307\n", 5, "at least 0.001"),  # (once a NaN pose in the first step)
        ("mass = -0.0\n", 5, "at least 0.001 and at most 1,000, not -0.0"),
        ("[encoders]\nticks_per_rev = " + "9" * 5000 + "\n", 6, "a whole number of 5000 digits"),
        ("[encoders]\nticks_per_rev = " + "9" * 400 + "\n", 6, "not a whole number of about 400 digits"),
        ("[mouse]\ndpi = 1e308\n", 6, "at most 1e+15, not 1e+308"),
        ("[belief]\ntrack_std = -0.01\n", 6, "[belief]: track_std: must be a number (relative) at least 0 and at most 0.5, not -0.01"),
        ("[belief]\ntrack_error = 0.01\n", 6, "[belief]: track_error: unknown key"),
    ],
)
def test_robot_values_at_the_edges_name_file_line_and_key(tmp_path, extra, line, message):
    path = tmp_path / "bot.toml"
    path.write_text(ROBOT + extra)
    with pytest.raises(FileError) as refused:
        load_robot(path)
    assert str(refused.value).startswith(f"{path}:{line}: ") and message in str(refused.value), refused.value


@pytest.mark.parametrize(
    "text, message",
    [
        ("[[start]]\nposition = [0, 0]\n[[movable]]\nposition = [1, 1]\nmass = 5e-324\n", "`mass` must be a number (kg) at least 0.001"),
        ("[[start]]\nposition = [0, 0]\n[[movable]]\nposition = [1, 1]\nradius = 5e-324\n", "`radius` must be a number (m) at least 0.001"),
        ("[[start]]\nposition = [0, 0]\n[grid]\ncell = 5e-324\nrows = '1X'\n", "`cell` must be a number (m) at least 0.001"),
        ("[[start]]\nposition = [5e-324, 0]\n", "subnormal"),
        ("[[start]]\nposition = [0, 0]\nslot = " + "7" * 5000 + "\n", "5000 digits"),
    ],
)
def test_world_values_at_the_edges_name_file_and_line(tmp_path, text, message):
    path = tmp_path / "w.toml"
    path.write_text(text)
    with pytest.raises(FileError) as refused:
        load_world(path)
    assert str(refused.value).startswith(f"{path}:") and message in str(refused.value), refused.value


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes are POSIX")
@pytest.mark.parametrize("name", ["bot.toml", "w.toml", "w.xml"])
def test_a_named_pipe_is_refused_at_once_not_waited_on(tmp_path, name):
    path = tmp_path / name
    os.mkfifo(path)
    load = load_robot if name == "bot.toml" else load_world
    with pytest.raises(FileError, match="not a regular file \\(a named pipe\\)"):
        load(path)  # (no writer ever opens it: a blocking read would hang here)


def test_a_folder_given_as_a_file_is_refused(tmp_path):
    (tmp_path / "bot.toml").mkdir()
    with pytest.raises(FileError, match="a folder"):
        load_robot(tmp_path / "bot.toml")


@pytest.mark.parametrize("name", ["bot.toml", "w.toml", "w.xml"])
def test_a_utf8_byte_order_mark_is_accepted(tmp_path, name):
    path = tmp_path / name
    text = {"bot.toml": ROBOT, "w.toml": "bounds = [-1, -1, 1, 1]\n[[start]]\nposition = [0, 0]\n", "w.xml": "<world><parcours><line>.1.</line></parcours></world>"}[name]
    path.write_bytes(b"\xef\xbb\xbf" + text.encode())
    loaded = load_robot(path) if name == "bot.toml" else load_world(path)
    assert loaded is not None


def checkerboard(side: int) -> str:
    """A parcours of `side` x `side` tiles, walls and start tiles alternating."""
    rows = ("".join("X" if (r + c) % 2 else "1" for c in range(side)) for r in range(side))
    return "<world><parcours>" + "".join(f"<line>{row}</line>\n" for row in rows) + "</parcours></world>"


def test_a_500_by_500_checkerboard_of_walls_and_starts_is_checked_within_the_budget(tmp_path):
    """125,000 starts beside 125,000 walls: all pairs would be 1.6e10 (hours); binned, each start
    looks at its neighbours only and the pairs looked at stay well inside the budget."""
    path = tmp_path / "board.xml"
    path.write_text(checkerboard(500))
    world = load_world(path)
    assert len(world.walls) == len(world.starts) == 125_000
    warnings = world_warnings(world)
    assert warnings == ["125000 starts share slot 1; the last one is used"]  # no start is within a robot's radius of a wall


def test_the_checks_stop_at_their_budget_and_say_so(tmp_path):
    path = tmp_path / "board.xml"
    path.write_text(checkerboard(40))
    warnings = world_warnings(load_world(path), budget=1000)
    assert warnings[-1].startswith("the checks stopped after looking at 1,000 pairs")


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(0.01, 3), st.floats(0.01, 3)), max_size=30),
       st.tuples(st.floats(-6, 6), st.floats(-6, 6)), st.floats(0, 1))
def test_binned_polygons_near_a_point_are_those_a_full_scan_finds(boxes, point, reach):
    polygons = [((x, y), (x + w, y), (x + w, y + h), (x, y + h)) for x, y, w, h in boxes]
    near = Near(polygons, Budget(10**9), most_cells=4)
    scanned = [i for i, (x, y, w, h) in enumerate(boxes) if math.hypot(max(x - point[0], 0, point[0] - x - w), max(y - point[1], 0, point[1] - y - h)) <= reach]
    assert near.near(point, reach) == scanned


def test_a_goal_far_outside_the_world_is_warned(tmp_path):
    path = tmp_path / "w.toml"
    path.write_text("bounds = [0, 0, 2, 2]\n[[start]]\nposition = [1, 1]\n[[goal]]\nbox = [50, 50, 51, 51]\n")
    assert any("goal #1 at (50.500, 50.500) is outside the world's bounds" in w for w in world_warnings(load_world(path)))


@pytest.mark.parametrize("offset, where", [(0.0, "inside"), (0.05, "0.035 m from")])
def test_a_start_on_a_movable_is_warned(tmp_path, offset, where):
    path = tmp_path / "w.toml"
    path.write_text(f"bounds = [0, 0, 2, 2]\n[[start]]\nposition = [1, 1]\n[[movable]]\nposition = [{1 + offset}, 1]\nradius = 0.015\n")
    assert any(f"start #1 (slot 0) at (1.000, 1.000) is {where} movable #1" in w for w in world_warnings(load_world(path)))


def test_a_misspelt_row_tag_and_other_unknown_tags_are_warned_with_their_line(tmp_path):
    path = tmp_path / "w.xml"
    path.write_text("<world>\n<parcours>\n<line>#1#</line>\n<lien>#.#</lien>\n<line>###</line>\n</parcours>\n<sky/>\n</world>")
    warnings = world_warnings(load_world(path))
    assert "line 4: unknown tag <lien> inside <parcours>, ignored; did you mean <line>?" in warnings
    assert any(w.startswith("line 7: unknown tag <sky> inside <world>, ignored (known there:") for w in warnings)


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX file kinds")
def test_a_device_is_refused_as_a_file():
    with pytest.raises(FileError, match="a character device"):
        load_robot("/dev/zero")


@pytest.mark.parametrize("line, message", [("number = nan", "number: must be a whole number at least 1 and at most 9,999, not nan"),
                                           ("number = 1\ntime_limit = 1e999", "time_limit: must be a number (s) greater than 0 and at most 3,600, not inf")])
def test_an_exercise_file_with_a_value_at_the_edge_names_file_and_key(tmp_path, line, message):
    from sim.lab.exercise import SHIPPED, ExerciseError, load_exercise

    folder = tmp_path / "ex"
    shutil.copytree(next(p for p in sorted(SHIPPED.iterdir()) if p.is_dir()), folder)
    toml = folder / "exercise.toml"
    toml.write_text(f"{line}\n" + "\n".join(row for row in toml.read_text().splitlines() if not row.startswith(("number", "time_limit"))))
    with pytest.raises(ExerciseError) as refused:
        load_exercise(folder)
    assert str(refused.value) == f"{toml}: {message}"



@pytest.mark.parametrize(
    "options, message",
    [
        (["--step-timeout", "1e308"], "argument --step-timeout: must be a number (s) at least 0.05 and at most 86,400, not 1e+308"),
        (["--export-rate", "5e-324"], "argument --export-rate: must be a number (Hz) greater than 0 and at most 1,000,000, not 5e-324: a subnormal"),
        (["--duration", "1e308"], "argument --duration: must be a number (s) greater than 0 and at most 10,000,000"),
        (["--duration", "nan"], "argument --duration: expected a finite number, got 'nan'"),
        (["--param", "speed_m_s=" + "9" * 5000], "argument --param: speed_m_s: a whole number of thousands of digits"),
        (["--seed", "9" * 5000], "argument --seed: expected a number, got one of 5,000 digits (at most 40)"),
        (["--robots", "9" * 5000], "argument --robots: expected a number, got one of 5,000 digits"),
        (["--robot-set", "mass=5e-324"], "mass: must be a number (kg) at least 0.001"),
    ],
)
def test_run_options_at_the_edges_are_one_line_naming_the_option(tmp_path, capsys, options, message):
    from sim.cli.entry import main

    try:
        code = main(["run", "empty", "--controller", "square", "--no-report", "--out", str(tmp_path / "out"), *options])
    except SystemExit as done:
        code = done.code
    err = capsys.readouterr().err
    assert code == 2 and message in err and err.count("\n") == 1 and len(err) < 400, err


@given(st.one_of(st.floats(), st.integers(max_value=-1), st.booleans(), st.none(), st.text(max_size=5), st.just(b"1"), st.just([1])))
@settings(max_examples=40)
def test_a_seed_that_is_not_a_whole_number_of_0_or_more_is_refused_naming_the_argument(seed):
    """Not numpy's TypeError, nor a run drawn from the operating system's entropy (None)."""
    from sim.errors import UserError
    from sim.experiments import simulate

    with pytest.raises(UserError, match=r"^seed must be a whole number of 0 or more \(an int\), got "):
        simulate("empty", duration=0.01, seed=seed)


@pytest.mark.parametrize("where", ["base", "sweep"])
@pytest.mark.parametrize("seed", [1.5, -1, True])
def test_a_sweeps_seed_that_is_not_a_whole_number_of_0_or_more_is_refused_naming_it(tmp_path, where, seed):
    from sim.experiments import Serial, sweep
    from sim.experiments.plan import SpecError

    with pytest.raises(SpecError, match=rf"\[{where}\].*seed: must be a whole number at least 0"):
        sweep({where: {"seed": seed}, "base" if where == "sweep" else "axes": {}}, tmp_path / "out", Serial(), progress=False)
