"""Noise presets of the c't-Bot and `section.field=value` overrides of any robot description.

A robot description is noise-free by default (exact ground truth for tests); `ctsim run` applies a
preset, named in the summary. The figures below are per 10 ms step where they are rates:

| field | realistic | harsh | why |
|---|---|---|---|
| encoders.diameter_error | (0, +0.3 %) | (0, +1 %) | two hand-mounted wheels never match exactly (assumed) |
| encoders.track_error | +1 % | +3 % | the tyres' contact line is ~1 mm wide on a 97.2 mm track (assumed) |
| encoders.slip_std | 1 % | 5 % | random slip on a smooth floor (assumed) |
| encoders.tick_noise | 0.1 % | 1 % | a spurious tick on a flickering light barrier (assumed) |
| mouse.scale_error | +3.75 % | +3.75 % | the real c't-Bot's ADNS-2610 reads 415 instead of 400 cpi |
| mouse.noise_std | 0.2 | 0.5 counts | sensor noise (assumed) |
| mouse.max_speed | - | 0.305 m/s | the ADNS-2610's 12 inch/s tracking limit (data sheet) |
| ir.noise_std | 5 mm | 15 mm | GP2D12 spread on grey walls (assumed) |
| line/border/light.noise_std | 5 | 20 raw units | CNY70 and LDR readings flicker (assumed) |
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
        "encoders.slip_std": 0.01,
        "encoders.tick_noise": 0.001,
        "mouse.scale_error": 0.0375,
        "mouse.noise_std": 0.2,
        "ir.noise_std": 0.005,
        "line.noise_std": 5.0,
        "border.noise_std": 5.0,
        "light.noise_std": 5.0,
    },
    "harsh": {
        "encoders.diameter_error": (0.0, 0.01),
        "encoders.track_error": 0.03,
        "encoders.slip_std": 0.05,
        "encoders.tick_noise": 0.01,
        "mouse.scale_error": 0.0375,
        "mouse.noise_std": 0.5,
        "mouse.max_speed": 0.305,
        "ir.noise_std": 0.015,
        "line.noise_std": 20.0,
        "border.noise_std": 20.0,
        "light.noise_std": 20.0,
    },
}
"""Preset name -> field overrides (see the module's table for the figures and their sources)."""


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
    """`replace(owner, **changes)`, a value its schema refuses a RobotSettingError naming `key`."""
    try:
        return replace(owner, **changes)
    except Problem as problem:
        raise RobotSettingError(f"{key}: {problem.message}") from None


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
    """`robot` with a noise preset applied (sections it lacks, e.g. no mouse, are skipped)."""
    if preset not in NOISE_PRESETS:
        raise RobotSettingError(f"unknown noise preset {preset!r} (known: {', '.join(NOISE_PRESETS)})")
    present = {k: v for k, v in NOISE_PRESETS[preset].items() if getattr(robot, k.partition(".")[0]) not in (None, ())}
    return with_settings(robot, present)
