"""The readers of every file kind a user gives (world TOML, c't-Sim parcours XML, robot TOML,
sweep spec) against structured garbage from hypothesis: the right keys with values of every kind
and size, unknown keys, nesting, broken XML. Whatever comes in, a reader returns its object or
raises its one user error (`bots.schema.FileError`, `SpecError`); never another exception, never
a hang (pytest-timeout would stop one and print where). A robot that loads is also put into a
world: Chipmunk aborted the process on a negative mass once. Each test tallies how many of its
files loaded: a strategy whose files are all refused would test the refusals alone, and fails.

CI runs a short budget; `CTSIM_FUZZ_EXAMPLES=6000 python -m pytest tests/test_fuzz_files.py
-p no:timeout` runs about ten minutes on one core (2500 took 4.5 minutes: 12,500 files).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from bots.schema import FileError
from bots.spec import load_robot
from sim.experiments.plan import OPTIONS, SETTINGS, SpecError, load_sweep
from sim.world import World
from sim.world.files import load_world, world_warnings
from sim.world.files.grid import KNOWN_TILES
from sim.world.files.toml_format import FIELDS

EXAMPLES = int(os.environ.get("CTSIM_FUZZ_EXAMPLES", "25"))
# (no shrink phase: shrinking structured garbage took minutes; a failure prints its seed to rerun)
FUZZ = settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None, phases=[Phase.explicit, Phase.reuse, Phase.generate],
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

numbers = st.one_of(
    st.integers(-(2**63), 2**63 - 1), st.floats(), st.sampled_from([0, -1, 1e-300, 1e300, 0.5, 60, 2**40]),
    st.floats(-2.0, 2.0),
)
scalars = st.one_of(numbers, st.booleans(), st.text(max_size=12), st.sampled_from(["#ff00ff", "left", "right", "grid", "random", "maze", "empty"]))
pairs = st.lists(numbers, min_size=0, max_size=5)
values = st.recursive(
    st.one_of(scalars, pairs),
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text("abcxyz_", min_size=1, max_size=6), inner, max_size=3)),
    max_leaves=12,
)


def toml_key(key: str) -> str:
    return json.dumps(key, ensure_ascii=False)


def toml_value(value) -> str:
    """Any of `values` as an inline TOML value (tables inline, so arrays of tables are lists of them)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf") if math.isinf(value) else repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=True)
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return "{" + ", ".join(f"{toml_key(k)} = {toml_value(v)}" for k, v in value.items()) + "}"


def toml_text(data: dict) -> str:
    return "".join(f"{toml_key(k)} = {toml_value(v)}\n" for k, v in data.items())


def tables(fields: dict, known_weight: int = 4) -> st.SearchStrategy[dict]:
    """Tables of known keys (most of them) and a few unknown ones, each with any value."""
    key = st.one_of(*([st.sampled_from(sorted(fields))] * known_weight), st.text("abcdefghij_", min_size=1, max_size=8))
    return st.dictionaries(key, values, max_size=6)


def well_typed(fields: dict) -> st.SearchStrategy[dict]:
    """Tables whose values mostly have the right kind, so that the checks behind the types run too."""
    kinds = {"number": numbers, "integer": st.integers(-5, 10**7), "boolean": st.booleans(), "text": scalars,
             "pair": st.lists(numbers, min_size=2, max_size=2), "box": st.lists(numbers, min_size=4, max_size=4),
             "points": st.lists(st.lists(st.floats(-3, 3), min_size=2, max_size=2), max_size=6), "colour": st.just("#80a0c0"),
             "table": st.dictionaries(st.sampled_from(list(KNOWN_TILES)), st.just("#000000"), max_size=2),
             "tables": st.just([]), "texts": st.lists(st.sampled_from(["tum", "recording", "x"]), max_size=2)}
    return st.fixed_dictionaries({}, optional={name: kinds[f.kind] for name, f in fields.items()})


IN_RANGE_KINDS = ("number", "integer", "boolean", "pair", "text")
"""The kinds `in_range` draws for any field; a field of another kind only when it has choices."""


def in_range(field) -> st.SearchStrategy:
    """Values a field accepts (its kind, inside its bounds, one of its choices), so that the code
    after the checks runs too."""
    if field.choices:
        return st.sampled_from(field.choices) if field.kind == "text" else st.lists(st.sampled_from(field.choices), max_size=2, unique=True)
    low, high = max(field.low, -1e6), min(field.high, 1e6)
    number = st.floats(low, high, exclude_min=field.above, allow_subnormal=False)
    return {"number": number, "integer": st.integers(math.ceil(low), math.floor(high)), "boolean": st.booleans(),
            "pair": st.lists(number, min_size=2, max_size=2), "text": st.text("abc", min_size=1, max_size=6)}[field.kind]


def sound(fields: dict) -> st.SearchStrategy[dict]:
    """Tables of in-range values for the fields `in_range` can draw."""
    return st.fixed_dictionaries({}, optional={name: in_range(f) for name, f in fields.items() if f.choices or f.kind in IN_RANGE_KINDS})


WORLD_TABLES = {name: f for name, f in FIELDS.items() if name not in (None, "grid.colours")}
START = {"start": [{"position": [0.5, 0.5]}]}
worlds = st.builds(
    lambda top, arrays, grid: {**top, **START, **arrays, **({"grid": grid} if grid else {})},
    tables(FIELDS[None]).map(lambda d: {k: v for k, v in d.items() if k != "grid"}),
    st.dictionaries(st.sampled_from([k for k in WORLD_TABLES if k != "grid"]),
                    st.lists(st.one_of(well_typed(FIELDS["wall"]), *(well_typed(f) for f in WORLD_TABLES.values()), tables(FIELDS["wall"])), max_size=3),
                    max_size=4),
    st.one_of(st.none(), well_typed(FIELDS["grid"]), st.fixed_dictionaries({"rows": st.text("#. 0123Z*LX|-=~", max_size=60)})),
)


coordinate = st.floats(-5, 5, allow_subnormal=False)
size = st.floats(0.001, 2)
boxes = st.builds(lambda x, y, w, h: [x, y, x + w, y + h], coordinate, coordinate, size, size)
sound_worlds = st.fixed_dictionaries(
    {"start": st.lists(st.fixed_dictionaries({"position": st.lists(coordinate, min_size=2, max_size=2)}, optional={"slot": st.integers(0, 5), "heading_deg": st.floats(-360, 360)}),
                       min_size=1, max_size=4), "bounds": st.just([-8, -8, 8, 8])},
    optional={"wall": st.lists(st.fixed_dictionaries({"box": boxes}), max_size=5), "goal": st.lists(st.fixed_dictionaries({"box": boxes}), max_size=2),
              "movable": st.lists(st.fixed_dictionaries({"position": st.lists(coordinate, min_size=2, max_size=2)}, optional={"radius": st.floats(0.001, 0.5), "mass": st.floats(0.001, 5)}),
                                  max_size=3),
              "grid": st.fixed_dictionaries({"rows": st.text("#. 012Z*LX|-=~", min_size=1, max_size=40).map(lambda r: r + "1")})},
)
"""Worlds made to load (every value in its range), so that the checks after loading run too."""


def robot_fields() -> dict:
    from bots.schema import schema_of
    from bots.spec import IRSensorSpec, LightSensorSpec, MotorSpec, RobotSpec

    return {"robot": schema_of(RobotSpec), "motor": schema_of(MotorSpec), "ir": schema_of(IRSensorSpec), "light": schema_of(LightSensorSpec)}


ROBOT = robot_fields()
BASE_ROBOT = {"name": "fuzz", "wheel_diameter": 0.0567, "track_width": 0.0972, "body_radius": 0.06}
robots = st.builds(
    lambda top, motor, ir, light: {**BASE_ROBOT, **top, **({"motor": motor} if motor is not None else {}), **({"ir": ir} if ir else {}),
                                   **({"light": light} if light else {})},
    st.one_of(well_typed(ROBOT["robot"]), tables(ROBOT["robot"])).map(lambda d: {k: v for k, v in d.items() if k not in ("motor", "encoders", "mouse", "ir", "line", "border", "light", "chassis")}),
    st.one_of(st.none(), well_typed(ROBOT["motor"]), tables(ROBOT["motor"])),
    st.lists(st.builds(lambda d: {"name": "i", "position": [0.05, 0.0], **d}, well_typed(ROBOT["ir"])), max_size=2),
    st.lists(st.builds(lambda d: {"name": "l", "position": [0.05, 0.0], **d}, well_typed(ROBOT["light"])), max_size=1),
)
sound_robots = st.builds(
    lambda top, motor: {**BASE_ROBOT, **top, "name": "fuzz", "motor": motor},
    sound({k: f for k, f in ROBOT["robot"].items() if k in ("mass", "skid", "contact")}), sound(ROBOT["motor"]),
)
"""Robots made to load (every value in its range), so that entering a world runs too."""
sweeps = st.fixed_dictionaries({}, optional={
    "sweep": st.one_of(tables({"mode": 0, "samples": 0, "seed": 0, "artefacts": 0}), values),
    "base": st.one_of(well_typed(SETTINGS), tables(SETTINGS)),
    "axes": st.dictionaries(st.sampled_from([*SETTINGS, "params.speed", "robot.mass", "bogus"]), st.one_of(st.lists(scalars, max_size=4), values), max_size=3),
})
SWEEP_AXES = {k: f for k, f in SETTINGS.items() if k in ("seed", "duration", "dt", "until_goal")}
sound_sweeps = st.fixed_dictionaries(
    {"base": st.fixed_dictionaries({"world": st.just("empty"), "controller": st.just("wander")}, optional={k: in_range(f) for k, f in SWEEP_AXES.items()}),
     "axes": st.fixed_dictionaries({}, optional={k: st.lists(in_range(f), min_size=1, max_size=3) for k, f in SWEEP_AXES.items()})},
    optional={"sweep": sound(OPTIONS)},
)
"""Sweeps made to load: known settings and options, in-range values."""


@pytest.fixture(scope="module")
def empty_world():
    return load_world("empty")


LEAST_LOADED = 0.2
"""Least share of a strategy's files that must load: a strategy that only ever produces refused
files would test the refusals alone (the examples are derandomized, so the share is fixed)."""


class Tally:
    """How many of a strategy's files loaded and how many were refused."""

    def __init__(self) -> None:
        self.loads = self.refused = 0

    def loaded(self, path: Path, text: str, load, error: type[Exception] = FileError):
        """`load(path)` of `text` written there, or None when it refuses the file with one line
        that starts with its name; any other exception fails the test."""
        path.write_text(text, encoding="utf-8")
        try:
            made = load(path)
        except error as err:
            assert str(err).startswith(str(path)) and "\n" not in str(err)
            self.refused += 1
            return None
        self.loads += 1
        return made

    def check(self) -> None:
        total = self.loads + self.refused
        assert total >= EXAMPLES // 2, f"only {total} files were generated"
        assert self.loads >= LEAST_LOADED * total, f"{self.loads} of {total} generated files loaded (at least {LEAST_LOADED:.0%} must)"


def test_world_files_load_or_say_what_is_wrong(tmp_path_factory):
    tally = Tally()

    @FUZZ
    @given(data=st.one_of(worlds, sound_worlds, sound_worlds))
    def one(data):
        world = tally.loaded(tmp_path_factory.mktemp("w") / "fuzz.toml", toml_text(data), load_world)
        if world is not None:
            world_warnings(world)

    one()
    tally.check()


xml_safe = st.text(st.characters(blacklist_characters="<>&", blacklist_categories=("Cs", "Cc")), max_size=20)
sound_xml = st.builds(
    lambda rows, extra: f'<?xml version="1.0"?>\n<world><description>{extra}</description><parcours>'
    + "".join(f"<line>{row}</line>" for row in rows) + "</parcours></world>",
    st.lists(st.text("#. 012Z*LX|-=~o", min_size=1, max_size=30), min_size=1, max_size=12).map(lambda rows: [*rows, "1"]),
    xml_safe,
)
"""Parcours made to load: known tiles, a start tile, text without markup."""
xml_text = st.builds(
    lambda rows, extra, optics: f'<?xml version="1.0"?>\n<world><description>{extra}</description><parcours>'
    + "".join(f"<line>{row}</line>" for row in rows) + f"</parcours>{optics}</world>",
    st.lists(st.text("#. 0123Z*LX|-=~&<>;", max_size=30), max_size=12),
    st.text(max_size=20),
    st.one_of(st.just(""), st.builds(lambda t, c: f'<optics><appearance type="{t}"><color type="diffuse">{c}</color><clone>{t}</clone></appearance></optics>',
                                     st.text(max_size=2), st.text("#0x1234567890abcdef", max_size=9))),
)


def test_parcours_files_load_or_say_what_is_wrong(tmp_path_factory):
    tally = Tally()

    @FUZZ
    @given(text=st.one_of(xml_text, xml_text.map(lambda t: t[: len(t) // 2]), st.text(max_size=200), sound_xml, sound_xml))
    def one(text):
        world = tally.loaded(tmp_path_factory.mktemp("x") / "fuzz.xml", text, load_world)
        if world is not None:
            world_warnings(world)

    one()
    tally.check()


def test_robot_files_load_or_say_what_is_wrong_and_a_loaded_robot_enters_a_world(tmp_path_factory, empty_world):
    tally = Tally()

    @FUZZ
    @given(data=st.one_of(robots, sound_robots, sound_robots))
    def one(data):
        robot = tally.loaded(tmp_path_factory.mktemp("r") / "fuzz.toml", toml_text(data), load_robot)
        if robot is not None:
            World(empty_world).add_robot(robot)

    one()
    tally.check()


def test_sweep_specs_load_or_say_what_is_wrong(tmp_path_factory):
    tally = Tally()

    @FUZZ
    @given(data=st.one_of(sweeps, sound_sweeps, sound_sweeps))
    def one(data):
        tally.loaded(tmp_path_factory.mktemp("s") / "fuzz.toml", toml_text(data), load_sweep, SpecError)

    one()
    tally.check()


def test_a_strategy_of_refused_files_alone_fails_the_tally(tmp_path):
    """The tally's own check: files that are all refused do not pass as a fuzz test."""
    tally = Tally()
    for k in range(EXAMPLES):
        tally.loaded(tmp_path / f"bad{k}.toml", "x = [", load_robot)
    with pytest.raises(AssertionError, match=f"0 of {EXAMPLES} generated files loaded"):
        tally.check()


def test_the_fuzz_text_is_toml_for_every_kind_of_value(tmp_path):
    """The serializer the fuzz tests rely on writes what tomllib reads back."""
    import tomllib

    data = {"a": [1, 2.5, float("inf")], "b": {"c": "x\"y", "d": [{"e": True}]}, "f g": -3}
    assert tomllib.loads(toml_text(data))["b"] == data["b"]
    assert Path(tmp_path).is_dir()
