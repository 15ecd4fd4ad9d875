"""Noise presets of the c't-Bot and `section.field=value` overrides of any robot description.

A robot description is noise-free by default (exact ground truth for tests); every way of starting
a run applies DEFAULT_NOISE (realistic) unless told `none` (`--noise none`, `noise="none"`), and
names it in the summary, the console table and the figures. Every random error is a process in distance (or in ticks counted),
never in steps, so the same seed-averaged drift comes out at any `--dt` (tests/test_noise_processes.py).

| field | realistic | harsh | source |
|---|---|---|---|
| encoders.diameter_error | (0, +0.3 %) | (0, +1 %) | Borenstein and Feng 1996 (UMBmark, IEEE T-RA 12(6)) name unequal wheel diameters and the uncertain effective wheelbase as the two dominant systematic errors of differential drives; the sizes are assumed: 0.3 % is 0.17 mm on the c't-Bot's 57 mm hand-mounted rubber tyres |
| encoders.track_error | +1 % | +3 % | the same paper's other dominant error; size assumed: the tyres' contact patch is about 1 mm wide on a 97.2 mm track |
| encoders.slip_std | 0.0004 | 0.002 sqrt m | model: variance growing with the distance rolled (Chong and Kleeman 1997); figure assumed: the 1 % per 10 ms step the earlier per-step model used, at the c't-Bot's normal 0.15 m/s (0.33 degrees of heading spread per root metre) |
| encoders.tick_noise | 0.002 | 0.02 per tick | assumed: the c't-Bot counts 60 edges a turn with CNY70 reflex sensors on a striped disc (30 black, 30 white), whose edges bounce in ambient light; the CNY70 data sheet gives no figure; 0.2 % is one wrong tick in 1.5 m |
| encoders.start_phase, mouse.start_phase | random | random | a real wheel and floor stop anywhere within a count: each counter starts at a phase drawn from the run's seed, so the count's error has zero mean (c't-Sim's counters, and a robot without a preset, start on an edge and lag by half a count on average) |
| mouse.scale_error | +3.75 % | +3.75 % | a stated measurement of the c't-Bot: the firmware's bot-local.h calibrates the real bot's ADNS-2610 at 415 cpi against its nominal 400 (`MOUSE_CPI`) |
| mouse.noise_std | 0.00033 | 0.0008 sqrt m | model: count error growing with the floor passed; figure assumed: the 0.2 counts per 10 ms step the earlier model used at 0.15 m/s (0.33 mm per root metre, 1.3 degrees of heading per root metre from a sensor 15 mm behind the axle); two-mice odometry measured 114 mm E_max,syst on UMBmark (Bonarini, Matteucci, Restelli 2004), comparable with wheel odometry |
| mouse.max_speed | - | 0.305 m/s | the ADNS-2610's 12 inch/s tracking limit (data sheet) |
| ir.noise_std | 5 mm | 15 mm | assumed: the GP2D12 application note (Zufferey) measures output noise below 200 mV with a spread independent of distance, and the data sheet a new reading every 38.3 +- 9.6 ms; 5 mm is 3 raw units of the c't-Bot's curve at 0.3 m, 12 at 0.15 m |
| line/border/light.noise_std | 5 | 20 raw units | assumed: neither the CNY70 nor the LDR data sheet gives a spread; 5 of the 10-bit range is half a percent of ambient-light flicker |
"""

from __future__ import annotations

import difflib
import tomllib
from dataclasses import fields, is_dataclass, replace
from typing import Any

from bots.schema import MAX_DIGITS, Problem
from bots.spec import RobotSpec
from sim.errors import UserError

NOISE_PRESETS: dict[str, dict[str, Any]] = {
    "none": {},
    "realistic": {
        "encoders.diameter_error": (0.0, 0.003),
        "encoders.track_error": 0.01,
        "encoders.slip_std": 0.0004,
        "encoders.tick_noise": 0.002,
        "encoders.start_phase": "random",
        "mouse.scale_error": 0.0375,
        "mouse.noise_std": 0.00033,
        "mouse.start_phase": "random",
        "ir.noise_std": 0.005,
        "line.noise_std": 5.0,
        "border.noise_std": 5.0,
        "light.noise_std": 5.0,
    },
    "harsh": {
        "encoders.diameter_error": (0.0, 0.01),
        "encoders.track_error": 0.03,
        "encoders.slip_std": 0.002,
        "encoders.tick_noise": 0.02,
        "encoders.start_phase": "random",
        "mouse.scale_error": 0.0375,
        "mouse.noise_std": 0.0008,
        "mouse.max_speed": 0.305,
        "mouse.start_phase": "random",
        "ir.noise_std": 0.015,
        "line.noise_std": 20.0,
        "border.noise_std": 20.0,
        "light.noise_std": 20.0,
    },
}
"""Preset name -> field overrides (see the module's table for the figures and their sources)."""

DEFAULT_NOISE = "realistic"
"""The preset of every way of starting a run (`ctsim run`, `play`, `simulate`, sweeps, contests, the
gym envs) unless told otherwise: the same call means the same physics everywhere. The firmware
bridge alone stays exact, as c't-Sim has no noise."""


DIFFERENTIAL_ONLY = ("encoders.diameter_error", "encoders.track_error")
"""Preset fields that describe a differential drive's two wheels (a general chassis refuses them)."""


class RobotSettingError(UserError):
    """An override that names no field of the robot or gives it a value of the wrong kind."""


def parse_value(text: str) -> Any:
    """A command-line value as TOML reads it (`0.02`, `true`, `[0, 0.01]`), else the text itself;
    ValueError for a whole number longer than `bots.schema.MAX_DIGITS`."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except (tomllib.TOMLDecodeError, RecursionError):  # (nested past Python's stack: not a value either)
        return text
    except ValueError:  # (a number past Python's digit limit)
        raise ValueError(f"a whole number of thousands of digits; ctsim's numbers have at most {MAX_DIGITS}") from None


def _closest(name: str, known: list[str]) -> str:
    close = difflib.get_close_matches(name, known, n=1)
    return f"; did you mean {close[0]!r}?" if close else f" (known: {', '.join(known)})"


def _checked(owner: Any, name: str, value: Any, key: str) -> Any:
    """`value` for `owner.name` as a robot file would give it, or a RobotSettingError naming `key`
    (the field's own Field checks the value when the spec is rebuilt, `_replaced`)."""
    known = [f.name for f in fields(owner)]
    if name not in known:
        raise RobotSettingError(f"{key}: {type(owner).__name__} has no field {name!r}{_closest(name, known)}")
    current = getattr(owner, name)
    if is_dataclass(current) or (isinstance(current, tuple) and current and is_dataclass(current[0])):
        raise RobotSettingError(f"{key}: a section, not a value; set one of its fields as {key}.FIELD")
    return tuple(value) if isinstance(value, list) else value


def _replaced(owner: Any, key: str, **changes: Any) -> Any:
    """`replace(owner, **changes)`, a value its schema refuses a RobotSettingError naming `key`,
    and the field whose check failed where that is another (min_range against the max_range set)."""
    try:
        return replace(owner, **changes)
    except Problem as problem:
        other = f"{problem.key} " if problem.key and problem.key not in changes else ""
        raise RobotSettingError(f"{key}: {other}{problem.message}") from None


def with_settings(robot: RobotSpec, settings: dict[str, Any]) -> RobotSpec:
    """`robot` with `section.field` (or top-level `field`) values replaced; a sensor list section
    (`ir`, `line`, `border`, `light`) sets the field on every sensor in it."""
    for key, value in settings.items():
        section, _, name = key.rpartition(".")
        if not section:
            robot = _replaced(robot, key, **{name: _checked(robot, name, value, key)})
            continue
        sections = [f.name for f in fields(robot) if is_dataclass(getattr(robot, f.name)) or isinstance(getattr(robot, f.name), tuple)]
        if section not in sections:
            raise RobotSettingError(f"{key}: a robot has no section {section!r}{_closest(section, sections)}")
        current = getattr(robot, section)
        if current is None:
            raise RobotSettingError(f"{key}: robot {robot.name!r} has no {section}")
        if isinstance(current, tuple) and all(is_dataclass(s) for s in current):
            changed = tuple(_replaced(s, key, **{name: _checked(s, name, value, key)}) for s in current)
        elif is_dataclass(current):
            changed = _replaced(current, key, **{name: _checked(current, name, value, key)})
        else:
            raise RobotSettingError(f"{key}: {section!r} is a value, not a section; set it as {section}=...")
        robot = _replaced(robot, key, **{section: changed})
    return robot


def with_noise(robot: RobotSpec, preset: str) -> RobotSpec:
    """`robot` with a noise preset applied (sections it lacks, e.g. no mouse, are skipped, and a
    general chassis, whose wheels carry their own real radii, keeps its wheel sizes)."""
    if preset not in NOISE_PRESETS:
        raise RobotSettingError(f"unknown noise preset {preset!r} (known: {', '.join(NOISE_PRESETS)})")
    present = {k: v for k, v in NOISE_PRESETS[preset].items() if getattr(robot, k.partition(".")[0]) not in (None, ())}
    if robot.chassis is not None:
        present = {k: v for k, v in present.items() if k not in DIFFERENTIAL_ONLY}
    return with_settings(robot, present)
