"""Bad world files: each mistake is a WorldFileError naming the file, the line and the problem."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sim.world.files import check_world, load_world, shipped_worlds
from sim.world.spec import WorldFileError

START = "[[start]]\nposition = [0.5, 0.5]\n"


def _error(tmp_path: Path, text: str, suffix: str = ".toml") -> WorldFileError:
    path = tmp_path / f"bad{suffix}"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(WorldFileError) as err:
        load_world(path)
    assert err.value.path == str(path)
    return err.value


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        # unknown keys, with the close match suggested
        (START + "[[wall]]\nfrom = [0, 0]\nto = [1, 0]\nthicknes = 0.1\n", 6, "unknown key `thicknes`; did you mean `thickness`?"),
        (START + "[[walls]]\nbox = [0, 0, 1, 1]\n", 3, "unknown key `walls`; did you mean `wall`?"),
        ("nmae = 'x'\n" + START, 1, "did you mean `name`?"),
        # geometry
        (START + "[[wall]]\nfrom = [1, 1]\nto = [1, 1]\n", 5, "the wall has no length"),
        (START + "[[floor]]\npolygon = [[0, 0], [1, 0], [0.2, 0.2], [0, 1]]\ncolour = '#ffffff'\n", 4, "must be convex"),
        (START + "[[hole]]\npolygon = [[0, 0], [1, 0]]\n", 4, "at least 3"),
        (START + "[[goal]]\nbox = [1, 1, 0, 2]\n", 4, "xmin < xmax"),
        (START + "[[wall]]\nbox = [0, 0, 1, 1]\nfrom = [0, 0]\n", 5, "give exactly one of"),
        (START + "[[line]]\npoints = [[1, 1], [1, 1]]\n", 4, "the line has no length"),
        # numbers and types
        (START + "[[light]]\nposition = [nan, 1]\n", 4, "at most 10,000, not [nan, 1]"),
        (START + "[[movable]]\nposition = [1, 1]\nradius = inf\n", 5, "at most 10, not inf"),
        (START + "[[wall]]\nfrom = [0, 0]\nto = [1, 0]\nthickness = 'thin'\n", 6, "must be a number (m) at least 0.001 and at most 10, not 'thin'"),
        (START + "[[wall]]\nfrom = [0, 0]\nto = [1, 0]\nthickness = -0.1\n", 6, "at least 0.001 and at most 10, not -0.1"),
        (START + "[[floor]]\nbox = [0, 0, 1, 1]\ncolour = 'white'\n", 5, 'must be a colour like "#a0b0c0"'),
        (START + "[[floor]]\nbox = [0, 0, 1, 1]\n", 3, "missing `colour`"),
        ("[[start]]\nposition = [0.5, true]\n", 2, "must be a list of 2 numbers (m)"),
        ("[[start]]\nposition = [0.5, 0.5]\nheading = 1\nheading_deg = 90\n", 3, "not both"),
        ("[[start]]\nposition = [0.5, 0.5]\nslot = 1.5\n", 3, "must be a whole number"),
        ("[start]\nposition = [0.5, 0.5]\n", 1, "must be written as [[start]]"),
        ("name = 3\n" + START, 1, "`name` must be a string"),
        (START + "bounds = [0, 0, 1]\n", None, None),  # after a table the key belongs to it: caught as unknown
        # TOML syntax, with tomllib's line
        (START + "[[wall]]\nfrom = [0, 0\n", 4, "TOML syntax"),
    ],
)
def test_toml_mistakes_name_file_line_and_problem(tmp_path: Path, text: str, line: int | None, message: str | None) -> None:
    err = _error(tmp_path, text)
    if message is None:
        assert "unknown key `bounds`" in err.problem
        return
    assert message in err.problem
    assert err.line == line
    assert str(err).startswith(f"{err.path}:{line}: ")


def test_no_start_is_an_error(tmp_path: Path) -> None:
    err = _error(tmp_path, "[[wall]]\nbox = [0, 0, 1, 1]\n")
    assert "no start pose" in err.problem and err.line is None


def test_error_in_the_nth_table_points_at_that_table(tmp_path: Path) -> None:
    walls = "".join(f"[[wall]]\nbox = [{i}, 0, {i + 0.5}, 1]\n" for i in range(3))
    err = _error(tmp_path, START + walls + "[[wall]]\nbox = [0, 0, 1, 1]\ncolor = '#000000'\n")
    assert err.line == 11 and "[[wall]] #4" in err.problem and "did you mean `colour`?" in err.problem


def test_grid_rows_that_look_like_headers_do_not_confuse_line_numbers(tmp_path: Path) -> None:
    text = "[grid]\nrows = '''\n[-]\n[1]\n'''\n[[wall]]\nbox = [0, 0, 1, 1]\nwidth = 2\n"
    err = _error(tmp_path, text)
    assert err.line == 8 and "[[wall]] #1" in err.problem


def test_unknown_grid_tile_names_its_row_line(tmp_path: Path) -> None:
    text = "name = 'g'\n[grid]\ncell = 0.24\nrows = '''\n#####\n#1 Z#\n#Q  #\n#####\n'''\n"
    err = _error(tmp_path, text)
    assert err.line == 7
    assert "unknown tile 'Q'" in err.problem and "column 2" in err.problem


def test_grid_colours_must_name_tiles(tmp_path: Path) -> None:
    err = _error(tmp_path, "[grid]\nrows = '''\n1\n'''\n[grid.colours]\n'.' = '#ffffff'\n'?' = '#000000'\n")
    assert err.line == 7 and "not a grid tile" in err.problem


def test_xml_syntax_error_names_its_line(tmp_path: Path) -> None:
    text = "<?xml version='1.0'?>\n<world>\n<parcours>\n<line>#1#</line>\n<line>###</lin>\n</parcours>\n</world>\n"
    err = _error(tmp_path, text, ".xml")
    assert err.line == 5 and "XML error" in err.problem


def test_xml_unknown_tile_names_the_line_of_its_line_element(tmp_path: Path) -> None:
    text = (
        '<?xml version="1.0"?>\n<!DOCTYPE collection SYSTEM "parcours.dtd">\n<world>\n  <parcours>\n'
        "    <line>#####</line>\n    <line>#1 ?#</line>\n    <line>#####</line>\n  </parcours>\n</world>\n"
    )
    err = _error(tmp_path, text, ".xml")
    assert err.line == 6 and "unknown tile '?'" in err.problem


def test_xml_bad_colour_names_its_line(tmp_path: Path) -> None:
    text = (
        "<world><parcours><line>1</line></parcours>\n<optics>\n<appearance type=' '>\n"
        "<color type='ambient'>#zz0000</color>\n</appearance></optics></world>\n"
    )
    err = _error(tmp_path, text, ".xml")
    assert err.line == 4 and "bad colour" in err.problem


def test_unknown_world_name_suggests_a_shipped_one() -> None:
    with pytest.raises(WorldFileError, match="did you mean 'maze'"):
        load_world("maz")


def test_missing_file_and_wrong_type(tmp_path: Path) -> None:
    with pytest.raises(WorldFileError, match="no such file"):
        load_world(tmp_path / "nothing.toml")
    with pytest.raises(WorldFileError, match="unknown world file type"):
        load_world(tmp_path / "world.json")


def test_check_world_warns_about_starts_in_walls_and_holes(tmp_path: Path) -> None:
    path = tmp_path / "w.toml"
    path.write_text(
        "bounds = [0, 0, 2, 2]\n"
        "[[wall]]\nbox = [0, 0, 1, 1]\n"
        "[[hole]]\nbox = [1.5, 1.5, 1.9, 1.9]\n"
        "[[start]]\nposition = [0.5, 0.5]\n"
        "[[start]]\nposition = [1.7, 1.7]\nslot = 1\n"
        "[[start]]\nposition = [1.04, 0.5]\nslot = 1\n",
        encoding="utf-8",
    )
    warnings = check_world(path)
    assert any("start #1" in w and "inside a wall" in w for w in warnings)
    assert any("start #2" in w and "over a hole" in w for w in warnings)
    assert any("start #3" in w and "closer than a c't-Bot's radius" in w for w in warnings)
    assert any("2 starts share slot 1" in w for w in warnings)


SEED_WORLDS = [Path(__file__).resolve().parents[1] / "worlds" / f"{n}.toml" for n in ("square", "maze", "holes_lights")]


@settings(max_examples=150, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    world=st.sampled_from(SEED_WORLDS),
    cut=st.floats(0, 1),
    junk=st.text(alphabet="[]=#\"'\n ,.0123456789abcxyz-_{}", max_size=12),
)
def test_mangled_files_give_world_file_errors_only(tmp_path: Path, world: Path, cut: float, junk: str) -> None:
    text = world.read_text(encoding="utf-8")
    at = int(cut * len(text))
    for suffix, mangled in ((".toml", text[:at] + junk + text[at:]), (".xml", f"<world><parcours><line>{junk}</line></parcours></world>")):
        path = tmp_path / f"mangled{suffix}"
        path.write_text(mangled, encoding="utf-8")
        try:
            load_world(path)
        except WorldFileError as e:
            assert e.problem and e.path == str(path)


def test_a_folder_named_like_a_shipped_world_does_not_hide_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`ctsim run --out maze` makes a folder `maze/`; the next `ctsim run` (world `maze` by default)
    in the same place still loads the shipped maze, not the folder ('unknown world file type')."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "maze").mkdir()
    assert load_world("maze").name == load_world(shipped_worlds()["maze"]).name
    (tmp_path / "corridor").mkdir()
    with pytest.raises(WorldFileError, match="no such world file or shipped world"):
        load_world("corridor")


@pytest.mark.parametrize("written", ["./maze", "maze/", "./maze/"])
def test_a_path_with_a_directory_part_is_that_path_and_a_folder_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, written: str) -> None:
    """`ctsim run ./maze` with a folder `maze/` here ran the shipped maze (pathlib drops `./`): a
    name written with a directory part is that path, and a folder is refused naming it as written."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "maze").mkdir()
    with pytest.raises(WorldFileError, match="is a folder, not a world file") as raised:
        load_world(written)
    assert raised.value.path == written
    with pytest.raises(WorldFileError, match="no such file"):
        load_world("./corridor")
